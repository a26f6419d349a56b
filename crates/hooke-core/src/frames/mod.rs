//! Where a run's frames go: binary PLY or OBJ files, one per frame, or one file streamed as the
//! frames come: a Blender point cache (`.pc2`) or a USD stage (`.usda`). Every file goes through [`crate::atomic_file`]: a
//! reader, or a run killed midway, never sees one half written.

use std::io::{Seek, SeekFrom, Write};
use std::path::{Path, PathBuf};

use glam::DVec3;

use crate::atomic_file::{AtomicFile, write_atomically};
use crate::collide::Collider;
use crate::mesh::{TextureCoordinates, write_ply_frame};

mod usda;

pub use usda::FrameTiming;
use usda::UsdaStream;

/// The formats `hooke run --output-format` writes.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum FrameFormat {
    /// `frame-NNNNNNN.ply`: binary PLY, float32 positions and the faces.
    Ply,
    /// `frame-NNNNNNN.obj`: positions, per-vertex normals and the faces, in the mesh's vertex
    /// order (what DCC tools import as an OBJ sequence).
    Obj,
    /// `frames.pc2`: Blender's point cache (the Mesh Cache modifier's format), every frame in
    /// one file, vertex order = the mesh's.
    Pc2,
    /// `frames.usda`: a USD stage, the cloth a `Mesh` with time-sampled `points` and `extent`,
    /// the colliders `Sphere`, `Capsule` and `Plane` prims, animated where they move.
    Usda,
}

impl FrameFormat {
    pub const ALL: [Self; 4] = [Self::Ply, Self::Obj, Self::Pc2, Self::Usda];

    pub fn name(self) -> &'static str {
        match self {
            Self::Ply => "ply",
            Self::Obj => "obj",
            Self::Pc2 => "pc2",
            Self::Usda => "usda",
        }
    }

    /// Every name, for an error that lists the choices: `ply, obj, pc2, usda`.
    pub fn choices() -> String {
        Self::ALL.map(Self::name).join(", ")
    }

    /// The format of this [`FrameFormat::name`].
    pub fn from_name(name: &str) -> Option<Self> {
        Self::ALL.into_iter().find(|f| f.name() == name)
    }

    /// The format of one file holding every frame that `path` names by its extension
    /// (`cloth.usda`, `cloth.pc2`); `None` for anything else, a directory's name say.
    pub fn of_single_file(path: &Path) -> Option<Self> {
        let extension = path.extension()?.to_str()?.to_ascii_lowercase();
        Self::from_name(&extension).filter(|f| matches!(f, Self::Pc2 | Self::Usda))
    }
}

/// Where frames go, from the path a user named: a directory, or one `.usda` or `.pc2` file
/// (whose directory then holds the run's other files).
#[derive(Clone, Debug, PartialEq)]
pub struct FrameDestination {
    pub directory: PathBuf,
    /// The one file every frame goes to, when the path named it.
    pub file: Option<PathBuf>,
    pub format: FrameFormat,
}

/// A format asked for that the output file's extension contradicts.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct FormatConflict {
    /// The format the extension names.
    pub named: FrameFormat,
    /// The format asked for.
    pub given: FrameFormat,
}

impl FrameDestination {
    /// The destination of `output` in `format` (default: the file's extension, else PLY).
    pub fn resolve(output: &Path, format: Option<FrameFormat>) -> Result<Self, FormatConflict> {
        let Some(named) = FrameFormat::of_single_file(output) else {
            return Ok(Self {
                directory: output.to_owned(),
                file: None,
                format: format.unwrap_or(FrameFormat::Ply),
            });
        };
        if let Some(given) = format.filter(|f| *f != named) {
            return Err(FormatConflict { named, given });
        }
        Ok(Self {
            directory: crate::atomic_file::directory_of(output).to_owned(),
            file: Some(output.to_owned()),
            format: named,
        })
    }
}

/// Writes a run's frames into a directory in one format.
#[derive(Debug)]
pub struct FrameWriter {
    directory: PathBuf,
    /// Where a format of one file (`.pc2`, `.usda`) writes it, if not `frames.<ext>` in `directory`.
    stream_path: Option<PathBuf>,
    name: String,
    triangles: Vec<[u32; 3]>,
    uvs: Option<TextureCoordinates>,
    timing: FrameTiming,
    sink: Sink,
    written: usize,
}

#[derive(Debug)]
enum Sink {
    Ply,
    Obj,
    Pc2(Option<Pc2Stream>),
    Usda(Option<UsdaStream>),
}

impl FrameWriter {
    /// Frames of the scene `name` (its mesh's `triangles` and texture coordinates `uvs`), a
    /// frame every `timing.frame_every` steps of `timing.dt`, into `directory`.
    pub fn new(
        directory: &Path,
        format: FrameFormat,
        name: &str,
        triangles: &[[u32; 3]],
        uvs: Option<&TextureCoordinates>,
        timing: FrameTiming,
    ) -> Self {
        Self {
            directory: directory.to_owned(),
            stream_path: None,
            name: name.to_owned(),
            triangles: triangles.to_vec(),
            uvs: uvs.cloned(),
            timing,
            sink: match format {
                FrameFormat::Ply => Sink::Ply,
                FrameFormat::Obj => Sink::Obj,
                FrameFormat::Pc2 => Sink::Pc2(None),
                FrameFormat::Usda => Sink::Usda(None),
            },
            written: 0,
        }
    }

    /// [`FrameWriter::new`] for a destination: into its directory, or its one file.
    pub fn to(
        destination: &FrameDestination,
        name: &str,
        triangles: &[[u32; 3]],
        uvs: Option<&TextureCoordinates>,
        timing: FrameTiming,
    ) -> Self {
        let mut writer = Self::new(
            &destination.directory,
            destination.format,
            name,
            triangles,
            uvs,
            timing,
        );
        writer.stream_path = destination.file.clone();
        writer
    }

    /// Whether frames carry the colliders (USD draws them; the others hold only the cloth), so
    /// a caller reads them back only then (on the GPU, dynamic balls cost a read-back).
    pub fn draws_colliders(&self) -> bool {
        matches!(self.sink, Sink::Usda(_))
    }

    pub fn frames_written(&self) -> usize {
        self.written
    }

    /// Where frame `step` goes (the one `.pc2` or `.usda` file holds them all).
    pub fn path(&self, step: u64) -> PathBuf {
        if let (Some(path), Sink::Pc2(_) | Sink::Usda(_)) = (&self.stream_path, &self.sink) {
            return path.clone();
        }
        self.directory.join(match self.sink {
            Sink::Ply => format!("frame-{step:07}.ply"),
            Sink::Obj => format!("frame-{step:07}.obj"),
            Sink::Pc2(_) => "frames.pc2".to_owned(),
            Sink::Usda(_) => "frames.usda".to_owned(),
        })
    }

    /// Writes the frame of step `step`: the cloth's positions and where the colliders are.
    pub fn write(
        &mut self,
        step: u64,
        positions: &[DVec3],
        colliders: &[Collider],
    ) -> std::io::Result<()> {
        let path = self.path(step);
        match &mut self.sink {
            Sink::Ply => write_ply_frame(&path, positions, &self.triangles, self.uvs.as_ref())?,
            Sink::Obj => write_atomically(&path, |w| {
                write_obj_frame(w, step, positions, &self.triangles, self.uvs.as_ref())
            })?,
            Sink::Pc2(stream) => {
                if stream.is_none() {
                    *stream = Some(Pc2Stream::create(&path, positions.len())?);
                }
                if let Some(stream) = stream {
                    stream.append(positions)?;
                }
            }
            Sink::Usda(stream) => {
                if stream.is_none() {
                    *stream = Some(UsdaStream::create(
                        &path,
                        &self.name,
                        self.timing,
                        positions.len(),
                        &self.triangles,
                        self.uvs.as_ref(),
                    )?);
                }
                if let Some(stream) = stream {
                    stream.append(step, positions, colliders)?;
                }
            }
        }
        self.written += 1;
        Ok(())
    }

    /// Completes a file that collects frames (`.pc2`): only now does it appear under its name.
    pub fn finish(self) -> std::io::Result<usize> {
        match self.sink {
            Sink::Pc2(Some(stream)) => stream.commit()?,
            Sink::Usda(Some(stream)) => stream.commit()?,
            _ => {}
        }
        Ok(self.written)
    }
}

/// One OBJ frame: `v`, then the texture coordinates `vt` if any, then area-weighted `vn` per
/// vertex, then `f v/vt/vn` (or `f v//vn`) with 1-based indices.
fn write_obj_frame(
    w: &mut dyn Write,
    step: u64,
    positions: &[DVec3],
    triangles: &[[u32; 3]],
    uvs: Option<&TextureCoordinates>,
) -> std::io::Result<()> {
    writeln!(w, "# written by hooke: step {step}")?;
    for p in positions {
        let p = p.as_vec3();
        writeln!(w, "v {} {} {}", p.x, p.y, p.z)?;
    }
    if let Some(uvs) = uvs {
        for [u, v] in &uvs.coordinates {
            writeln!(w, "vt {} {}", *u as f32, *v as f32)?;
        }
    }
    for n in vertex_normals(positions, triangles) {
        writeln!(w, "vn {} {} {}", n.x, n.y, n.z)?;
    }
    for (k, t) in triangles.iter().enumerate() {
        let [a, b, c] = t.map(|i| i + 1);
        match uvs {
            Some(uvs) => {
                let [ta, tb, tc] = uvs.corners[k].map(|i| i + 1);
                writeln!(w, "f {a}/{ta}/{a} {b}/{tb}/{b} {c}/{tc}/{c}")?;
            }
            None => writeln!(w, "f {a}//{a} {b}//{b} {c}//{c}")?,
        }
    }
    Ok(())
}

/// Unit normals per vertex: the sum of the adjacent triangles' area-weighted normals (zero for
/// a vertex no triangle uses).
pub fn vertex_normals(positions: &[DVec3], triangles: &[[u32; 3]]) -> Vec<glam::Vec3> {
    let mut sums = vec![DVec3::ZERO; positions.len()];
    for t in triangles {
        let [a, b, c] = t.map(|i| positions[i as usize]);
        // Twice the area times the unit normal.
        let n = (b - a).cross(c - a);
        for &i in t {
            sums[i as usize] += n;
        }
    }
    sums.iter()
        .map(|n| n.normalize_or_zero().as_vec3())
        .collect()
}

/// Blender's point cache 2: a 32-byte header, then float32 `x y z` per point per sample.
#[derive(Debug)]
struct Pc2Stream {
    file: AtomicFile,
    points: usize,
    samples: u32,
}

/// Byte offset of the header's sample count.
const PC2_SAMPLE_COUNT_OFFSET: u64 = 28;

impl Pc2Stream {
    fn create(path: &Path, points: usize) -> std::io::Result<Self> {
        let mut file = AtomicFile::create(path)?;
        let points_field = i32::try_from(points)
            .map_err(|_| std::io::Error::other("too many vertices for a .pc2 file"))?;
        let w = file.writer();
        w.write_all(b"POINTCACHE2\0")?;
        w.write_all(&1i32.to_le_bytes())?; // file version
        w.write_all(&points_field.to_le_bytes())?;
        // Sample k is Blender frame 1 + k: the Mesh Cache modifier's default frame start.
        w.write_all(&1f32.to_le_bytes())?; // start frame
        w.write_all(&1f32.to_le_bytes())?; // frames per sample
        w.write_all(&0i32.to_le_bytes())?; // samples, set at commit
        Ok(Self {
            file,
            points,
            samples: 0,
        })
    }

    fn append(&mut self, positions: &[DVec3]) -> std::io::Result<()> {
        if positions.len() != self.points {
            return Err(std::io::Error::other(format!(
                ".pc2 frame of {} points in a file of {}",
                positions.len(),
                self.points
            )));
        }
        let w = self.file.writer();
        for p in positions {
            for value in p.as_vec3().to_array() {
                w.write_all(&value.to_le_bytes())?;
            }
        }
        self.samples += 1;
        Ok(())
    }

    fn commit(mut self) -> std::io::Result<()> {
        let w = self.file.writer();
        w.seek(SeekFrom::Start(PC2_SAMPLE_COUNT_OFFSET))?;
        w.write_all(&(self.samples as i32).to_le_bytes())?;
        w.seek(SeekFrom::End(0))?;
        self.file.commit()
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn square() -> (Vec<DVec3>, Vec<[u32; 3]>) {
        (
            vec![
                DVec3::new(0.0, 0.0, 0.0),
                DVec3::new(1.0, 0.0, 0.0),
                DVec3::new(0.0, 1.0, 0.0),
                DVec3::new(1.0, 1.0, 0.0),
            ],
            vec![[0, 1, 2], [1, 3, 2]],
        )
    }

    fn writer(dir: &Path, format: FrameFormat, triangles: &[[u32; 3]]) -> FrameWriter {
        let timing = FrameTiming {
            dt: 1e-3,
            frame_every: 10,
        };
        FrameWriter::new(dir, format, "square", triangles, None, timing)
    }

    #[test]
    fn pc2_holds_every_frame_in_order_and_appears_only_when_finished() {
        let dir = tempfile::tempdir().expect("tempdir");
        let (positions, triangles) = square();
        let mut writer = writer(dir.path(), FrameFormat::Pc2, &triangles);
        for step in 0..3u64 {
            let moved: Vec<DVec3> = positions
                .iter()
                .map(|p| *p + DVec3::Z * step as f64)
                .collect();
            writer.write(step * 10, &moved, &[]).expect("frame");
        }
        let path = dir.path().join("frames.pc2");
        assert!(!path.exists(), "the file appears only when complete");
        assert_eq!(writer.finish().expect("finished"), 3);
        let bytes = std::fs::read(&path).expect("read");
        assert_eq!(&bytes[..12], b"POINTCACHE2\0");
        let int = |at: usize| i32::from_le_bytes(bytes[at..at + 4].try_into().expect("4 bytes"));
        let float = |at: usize| f32::from_le_bytes(bytes[at..at + 4].try_into().expect("4 bytes"));
        assert_eq!((int(12), int(16), int(28)), (1, 4, 3));
        assert_eq!(bytes.len(), 32 + 3 * 4 * 12);
        // Sample 2, vertex 3: (1, 1, 2).
        let at = 32 + (2 * 4 + 3) * 12;
        assert_eq!([float(at), float(at + 4), float(at + 8)], [1.0, 1.0, 2.0]);
        let leftovers = std::fs::read_dir(dir.path()).expect("list").count();
        assert_eq!(leftovers, 1, "no temporary left");
    }

    #[test]
    fn obj_frames_keep_vertex_order_with_normals() {
        let dir = tempfile::tempdir().expect("tempdir");
        let (positions, triangles) = square();
        let mut writer = writer(dir.path(), FrameFormat::Obj, &triangles);
        writer.write(7, &positions, &[]).expect("frame");
        let text = std::fs::read_to_string(dir.path().join("frame-0000007.obj")).expect("written");
        let lines: Vec<&str> = text.lines().collect();
        assert_eq!(lines[2], "v 1 0 0");
        assert_eq!(lines[5], "vn 0 0 1");
        assert_eq!(lines.last(), Some(&"f 2//2 4//4 3//3"));
        assert_eq!(writer.finish().expect("done"), 1);
    }

    #[test]
    fn obj_frames_carry_texture_coordinates_per_corner() {
        let dir = tempfile::tempdir().expect("tempdir");
        let (positions, triangles) = square();
        let uvs = TextureCoordinates {
            coordinates: vec![[0.0, 0.0], [1.0, 0.0], [0.0, 1.0], [1.0, 1.0], [0.25, 0.5]],
            corners: vec![[0, 1, 2], [4, 3, 2]],
        };
        let timing = FrameTiming {
            dt: 1e-3,
            frame_every: 1,
        };
        let mut writer = FrameWriter::new(
            dir.path(),
            FrameFormat::Obj,
            "s",
            &triangles,
            Some(&uvs),
            timing,
        );
        writer.write(0, &positions, &[]).expect("frame");
        let text = std::fs::read_to_string(dir.path().join("frame-0000000.obj")).expect("written");
        assert!(text.contains("\nvt 0.25 0.5\n"), "{text}");
        assert_eq!(text.lines().last(), Some("f 2/5/2 4/4/4 3/3/3"));
    }

    #[test]
    fn a_streamed_format_goes_to_the_file_it_is_given() {
        let dir = tempfile::tempdir().expect("tempdir");
        let (positions, triangles) = square();
        let path = dir.path().join("cloth.pc2");
        let destination = FrameDestination::resolve(&path, None).expect("a .pc2 file");
        assert_eq!(destination.format, FrameFormat::Pc2);
        let timing = FrameTiming {
            dt: 1e-3,
            frame_every: 10,
        };
        let mut writer = FrameWriter::to(&destination, "square", &triangles, None, timing);
        assert_eq!(writer.path(10), path);
        writer.write(0, &positions, &[]).expect("frame");
        writer.finish().expect("finished");
        assert!(path.exists() && !dir.path().join("frames.pc2").exists());
    }
}
