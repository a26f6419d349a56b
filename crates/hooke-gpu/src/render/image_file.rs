//! Rendered images as PNG files, written atomically (a temporary file renamed into place).

use std::io::{BufWriter, Write};
use std::path::Path;

/// An 8-bit RGBA image.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct Image {
    pub size: [u32; 2],
    /// Tightly packed rows, 4 bytes per pixel.
    pub rgba: Vec<u8>,
}

#[derive(Debug, thiserror::Error)]
pub enum ImageError {
    #[error("{path}: {message}")]
    Io { path: String, message: String },
    #[error("{path}: not an 8-bit RGB or RGBA PNG ({found})")]
    Format { path: String, found: String },
}

fn io_error(path: &Path) -> impl Fn(String) -> ImageError + '_ {
    move |message| ImageError::Io {
        path: path.display().to_string(),
        message,
    }
}

impl Image {
    pub fn save_png(&self, path: &Path) -> Result<(), ImageError> {
        let error = io_error(path);
        let directory = path
            .parent()
            .filter(|p| !p.as_os_str().is_empty())
            .unwrap_or(Path::new("."));
        let temporary =
            tempfile::NamedTempFile::new_in(directory).map_err(|e| error(e.to_string()))?;
        {
            let mut writer = BufWriter::new(temporary.as_file());
            let mut encoder = png::Encoder::new(&mut writer, self.size[0], self.size[1]);
            encoder.set_color(png::ColorType::Rgba);
            encoder.set_depth(png::BitDepth::Eight);
            let mut png = encoder.write_header().map_err(|e| error(e.to_string()))?;
            png.write_image_data(&self.rgba)
                .map_err(|e| error(e.to_string()))?;
            png.finish().map_err(|e| error(e.to_string()))?;
            writer.flush().map_err(|e| error(e.to_string()))?;
        }
        temporary
            .persist(path)
            .map_err(|e| error(e.error.to_string()))?;
        Ok(())
    }

    pub fn load_png(path: &Path) -> Result<Self, ImageError> {
        let error = io_error(path);
        let file = std::fs::File::open(path).map_err(|e| error(e.to_string()))?;
        let mut reader = png::Decoder::new(std::io::BufReader::new(file))
            .read_info()
            .map_err(|e| error(e.to_string()))?;
        let mut buffer = vec![0; reader.output_buffer_size().unwrap_or(0)];
        let info = reader
            .next_frame(&mut buffer)
            .map_err(|e| error(e.to_string()))?;
        let rgba = match (info.color_type, info.bit_depth) {
            (png::ColorType::Rgba, png::BitDepth::Eight) => buffer[..info.buffer_size()].to_vec(),
            (png::ColorType::Rgb, png::BitDepth::Eight) => buffer[..info.buffer_size()]
                .chunks(3)
                .flat_map(|p| [p[0], p[1], p[2], 255])
                .collect(),
            (color, depth) => {
                return Err(ImageError::Format {
                    path: path.display().to_string(),
                    found: format!("{color:?}, {depth:?}"),
                });
            }
        };
        Ok(Self {
            size: [info.width, info.height],
            rgba,
        })
    }
}
