//! Rendered images as PNG files, written atomically (a temporary file renamed into place).

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
        hooke_core::atomic_file::write_atomically(path, |writer| {
            let mut encoder = png::Encoder::new(writer, self.size[0], self.size[1]);
            encoder.set_color(png::ColorType::Rgba);
            encoder.set_depth(png::BitDepth::Eight);
            let mut png = encoder.write_header().map_err(std::io::Error::other)?;
            png.write_image_data(&self.rgba)
                .map_err(std::io::Error::other)?;
            png.finish().map_err(std::io::Error::other)
        })
        .map_err(|e| io_error(path)(e.to_string()))
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

/// How two images of the same size differ.
#[derive(Clone, Debug, PartialEq)]
pub struct ImageDifference {
    /// Largest difference of any channel (0..255).
    pub max: u8,
    /// Share of pixels with a channel differing by more than the per-pixel threshold.
    pub differing_share: f64,
    /// Red where pixels differ beyond the threshold, the expected image faded elsewhere.
    pub diff: Image,
}

impl Image {
    /// Compares with `expected`; a pixel differs when every pixel of `expected` within `shift`
    /// pixels of it (0: only the same one) has a channel off by more than `threshold`. A
    /// `shift` of 1 lets edges and one-pixel lines land a pixel over, as rasterisers may.
    pub fn difference(
        &self,
        expected: &Image,
        threshold: u8,
        shift: u32,
    ) -> Option<ImageDifference> {
        if self.size != expected.size {
            return None;
        }
        let [width, height] = self.size.map(|d| d as i64);
        let pixel = |image: &Image, x: i64, y: i64| {
            let at = 4 * (y * width + x) as usize;
            [
                image.rgba[at],
                image.rgba[at + 1],
                image.rgba[at + 2],
                image.rgba[at + 3],
            ]
        };
        let off = |a: [u8; 4], e: [u8; 4]| (0..4).map(|c| a[c].abs_diff(e[c])).max().unwrap_or(0);
        let shift = i64::from(shift);
        let mut max = 0u8;
        let mut differing = 0usize;
        let mut diff = Vec::with_capacity(self.rgba.len());
        for y in 0..height {
            for x in 0..width {
                let a = pixel(self, x, y);
                let e = pixel(expected, x, y);
                let mut best = off(a, e);
                for ny in (y - shift).max(0)..=(y + shift).min(height - 1) {
                    for nx in (x - shift).max(0)..=(x + shift).min(width - 1) {
                        best = best.min(off(a, pixel(expected, nx, ny)));
                    }
                }
                max = max.max(best);
                if best > threshold {
                    differing += 1;
                    diff.extend([255, 0, 0, 255]);
                } else {
                    diff.extend([e[0] / 3 + 170, e[1] / 3 + 170, e[2] / 3 + 170, 255]);
                }
            }
        }
        Some(ImageDifference {
            max,
            differing_share: differing as f64 / (self.rgba.len() / 4).max(1) as f64,
            diff: Image {
                size: self.size,
                rgba: diff,
            },
        })
    }
}
