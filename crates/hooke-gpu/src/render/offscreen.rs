//! A texture to render into without a window, and reading its pixels back.

use crate::context::{GpuContext, GpuError};

/// An RGBA8 (sRGB) colour target of a fixed size.
#[derive(Debug)]
pub struct OffscreenTarget {
    texture: wgpu::Texture,
    pub view: wgpu::TextureView,
    pub size: [u32; 2],
}

impl OffscreenTarget {
    pub const FORMAT: wgpu::TextureFormat = wgpu::TextureFormat::Rgba8UnormSrgb;

    pub fn new(context: &GpuContext, size: [u32; 2]) -> Self {
        let texture = context.device.create_texture(&wgpu::TextureDescriptor {
            label: Some("offscreen colour"),
            size: wgpu::Extent3d {
                width: size[0],
                height: size[1],
                depth_or_array_layers: 1,
            },
            mip_level_count: 1,
            sample_count: 1,
            dimension: wgpu::TextureDimension::D2,
            format: Self::FORMAT,
            usage: wgpu::TextureUsages::RENDER_ATTACHMENT | wgpu::TextureUsages::COPY_SRC,
            view_formats: &[],
        });
        let view = texture.create_view(&Default::default());
        Self {
            texture,
            view,
            size,
        }
    }

    /// Rows of a texture copy must be 256-byte aligned.
    fn padded_row(&self) -> u32 {
        (4 * self.size[0]).div_ceil(wgpu::COPY_BYTES_PER_ROW_ALIGNMENT)
            * wgpu::COPY_BYTES_PER_ROW_ALIGNMENT
    }

    /// Records a copy of the image into `buffer` (see [`OffscreenTarget::readback_buffer`]).
    pub fn encode_copy(&self, encoder: &mut wgpu::CommandEncoder, buffer: &wgpu::Buffer) {
        encoder.copy_texture_to_buffer(
            self.texture.as_image_copy(),
            wgpu::TexelCopyBufferInfo {
                buffer,
                layout: wgpu::TexelCopyBufferLayout {
                    offset: 0,
                    bytes_per_row: Some(self.padded_row()),
                    rows_per_image: Some(self.size[1]),
                },
            },
            wgpu::Extent3d {
                width: self.size[0],
                height: self.size[1],
                depth_or_array_layers: 1,
            },
        );
    }

    /// A mappable buffer that holds one image.
    pub fn readback_buffer(&self, context: &GpuContext) -> wgpu::Buffer {
        context.device.create_buffer(&wgpu::BufferDescriptor {
            label: Some("image read-back"),
            size: u64::from(self.padded_row()) * u64::from(self.size[1]),
            usage: wgpu::BufferUsages::MAP_READ | wgpu::BufferUsages::COPY_DST,
            mapped_at_creation: false,
        })
    }

    /// Waits for `buffer` (filled by [`OffscreenTarget::encode_copy`]) and returns tightly
    /// packed RGBA8 rows.
    pub fn read_rgba(
        &self,
        context: &GpuContext,
        buffer: &wgpu::Buffer,
    ) -> Result<Vec<u8>, GpuError> {
        crate::gpu::map_blocking(context, buffer)?;
        let row = 4 * self.size[0] as usize;
        let padded = self.padded_row() as usize;
        let pixels = {
            let view = buffer
                .slice(..)
                .get_mapped_range()
                .map_err(|e| GpuError::ReadBack(e.to_string()))?;
            view.chunks(padded)
                .flat_map(|r| r[..row].to_vec())
                .collect()
        };
        buffer.unmap();
        Ok(pixels)
    }
}
