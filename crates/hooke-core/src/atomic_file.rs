//! Writing a file so that readers, and a run killed midway, never see it half written: the data
//! goes to a temporary file in the same directory, which is then renamed over the target. A run
//! killed while writing leaves the previous file (or none) and a `.NAME.XXXXXX.partial`.

use std::io::{BufWriter, Write};
use std::path::{Path, PathBuf};

use tempfile::NamedTempFile;

/// The directory a file named `path` goes in (`.` for a bare name).
pub fn directory_of(path: &Path) -> &Path {
    path.parent()
        .filter(|p| !p.as_os_str().is_empty())
        .unwrap_or(Path::new("."))
}

/// Writes `path` through `write`, atomically. The file gets the usual `rw-r--r--` mode.
pub fn write_atomically(
    path: &Path,
    write: impl FnOnce(&mut dyn Write) -> std::io::Result<()>,
) -> std::io::Result<()> {
    let mut file = AtomicFile::create(path)?;
    write(file.writer())?;
    file.commit()
}

/// A file written in pieces over a long run (frames as they come), which appears under its
/// name only when [`AtomicFile::commit`] is called: until then, and if the run is killed, the
/// previous file (or none) stays, beside a `.NAME.XXXXXX.partial`. Dropped without a commit,
/// the temporary is removed.
#[derive(Debug)]
pub struct AtomicFile {
    path: PathBuf,
    writer: BufWriter<NamedTempFile>,
}

impl AtomicFile {
    pub fn create(path: &Path) -> std::io::Result<Self> {
        let directory = directory_of(path);
        // A hidden `.NAME.XXXXXX.partial` beside the target: a run killed mid-write leaves one,
        // named so that nobody takes it for output.
        let name = path
            .file_name()
            .map(|n| n.to_string_lossy().into_owned())
            .unwrap_or_default();
        let temporary = tempfile::Builder::new()
            .prefix(&format!(".{name}."))
            .suffix(".partial")
            .tempfile_in(directory)?;
        Ok(Self {
            path: path.to_owned(),
            writer: BufWriter::new(temporary),
        })
    }

    /// Where the data goes; seekable, for headers that count what follows.
    pub fn writer(&mut self) -> &mut BufWriter<NamedTempFile> {
        &mut self.writer
    }

    /// Flushes, syncs and renames the file into place, with the usual `rw-r--r--` mode.
    pub fn commit(self) -> std::io::Result<()> {
        let temporary = self.writer.into_inner().map_err(|e| e.into_error())?;
        temporary.as_file().sync_data()?;
        #[cfg(unix)]
        {
            use std::os::unix::fs::PermissionsExt;
            // Temporary files are private (0600); an output file is not.
            temporary
                .as_file()
                .set_permissions(std::fs::Permissions::from_mode(0o644))?;
        }
        temporary.persist(&self.path).map_err(|e| e.error)?;
        Ok(())
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn failed_write_leaves_neither_target_nor_temporary() {
        let dir = tempfile::tempdir().expect("tempdir");
        let path = dir.path().join("out.bin");
        let result = write_atomically(&path, |w: &mut dyn Write| {
            w.write_all(b"partial")?;
            Err(std::io::Error::other("interrupted"))
        });
        assert!(result.is_err());
        assert_eq!(std::fs::read_dir(dir.path()).expect("list").count(), 0);
    }

    #[cfg(unix)]
    #[test]
    fn written_file_is_readable_by_others() {
        use std::os::unix::fs::PermissionsExt;
        let dir = tempfile::tempdir().expect("tempdir");
        let path = dir.path().join("out.bin");
        write_atomically(&path, |w| w.write_all(b"done")).expect("written");
        let mode = std::fs::metadata(&path)
            .expect("metadata")
            .permissions()
            .mode();
        assert_eq!(mode & 0o777, 0o644);
        assert_eq!(std::fs::read(&path).expect("read"), b"done");
    }
}
