//! Finding the cloth vertex under the cursor on the GPU (see pick.wgsl), read back
//! asynchronously: the answer arrives a frame or two later, and no frame waits for it.

use bytemuck::{Pod, Zeroable};
use glam::{Vec2, Vec3};

use super::Camera;
use super::readback::AsyncReadback;
use crate::context::{GpuContext, GpuError};
use crate::gpu::{self, bind_group, compute_pipeline};

pub(super) const PICK: &str = concat!(
    include_str!("../kernels/workgroup.wgsl"),
    include_str!("pick.wgsl")
);

#[repr(C)]
#[derive(Clone, Copy, Debug, Pod, Zeroable)]
struct PickUniforms {
    view_projection: [[f32; 4]; 4],
    cursor: [f32; 4],
    vertex_count: u32,
    _pad: [u32; 3],
}

#[repr(C)]
#[derive(Clone, Copy, Debug, Pod, Zeroable)]
struct PickResult {
    key: u32,
    vertex: u32,
    _pad: [u32; 2],
    position: [f32; 4],
}

/// Where to look: a cursor in normalised device coordinates on an image of `size` pixels,
/// within `radius_pixels` of it.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct PickAt {
    pub cursor: Vec2,
    pub size: [u32; 2],
    pub radius_pixels: f32,
}

/// A vertex found under the cursor.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct PickedVertex {
    pub vertex: u32,
    pub position: Vec3,
}

#[derive(Debug)]
pub struct Picker {
    closest: wgpu::ComputePipeline,
    which: wgpu::ComputePipeline,
    fetch: wgpu::ComputePipeline,
    uniforms: wgpu::Buffer,
    result: wgpu::Buffer,
    readback: AsyncReadback,
    vertex_count: u32,
}

impl Picker {
    pub fn new(context: &GpuContext, vertex_count: u32) -> Result<Self, GpuError> {
        Ok(Self {
            closest: compute_pipeline(context, "pick closest", PICK, "closest")?,
            which: compute_pipeline(context, "pick which", PICK, "which")?,
            fetch: compute_pipeline(context, "pick fetch", PICK, "fetch")?,
            uniforms: context.device.create_buffer(&wgpu::BufferDescriptor {
                label: Some("pick uniforms"),
                size: std::mem::size_of::<PickUniforms>() as u64,
                usage: wgpu::BufferUsages::UNIFORM | wgpu::BufferUsages::COPY_DST,
                mapped_at_creation: false,
            }),
            result: gpu::zeroed(
                context,
                "pick result",
                std::mem::size_of::<PickResult>() as u64,
                wgpu::BufferUsages::COPY_SRC | wgpu::BufferUsages::COPY_DST,
            ),
            readback: AsyncReadback::new(
                context,
                "pick read-back",
                std::mem::size_of::<PickResult>() as u64,
            ),
            vertex_count,
        })
    }

    /// Whether a pick can be started (the previous answer has been taken).
    pub fn is_idle(&self) -> bool {
        self.readback.is_idle()
    }

    /// Records a pick; false if the previous one has not been answered yet.
    pub fn encode(
        &self,
        context: &GpuContext,
        encoder: &mut wgpu::CommandEncoder,
        positions: &wgpu::Buffer,
        camera: &Camera,
        at: PickAt,
    ) -> bool {
        let PickAt {
            cursor,
            size,
            radius_pixels,
        } = at;
        if !self.is_idle() {
            return false;
        }
        let aspect = size[0] as f32 / size[1].max(1) as f32;
        let uniforms = PickUniforms {
            view_projection: camera.view_projection(aspect).to_cols_array_2d(),
            cursor: [
                cursor.x,
                cursor.y,
                2.0 * radius_pixels / size[0].max(1) as f32,
                2.0 * radius_pixels / size[1].max(1) as f32,
            ],
            vertex_count: self.vertex_count,
            _pad: [0; 3],
        };
        context
            .queue
            .write_buffer(&self.uniforms, 0, bytemuck::bytes_of(&uniforms));
        let empty = PickResult {
            key: u32::MAX,
            vertex: u32::MAX,
            _pad: [0; 2],
            position: [0.0; 4],
        };
        context
            .queue
            .write_buffer(&self.result, 0, bytemuck::bytes_of(&empty));
        let resources = [
            (0, self.uniforms.as_entire_binding()),
            (1, positions.as_entire_binding()),
            (2, self.result.as_entire_binding()),
        ];
        for (label, pipeline, count) in [
            ("pick closest", &self.closest, self.vertex_count),
            ("pick which", &self.which, self.vertex_count),
            ("pick fetch", &self.fetch, 1),
        ] {
            let group = bind_group(
                context,
                label,
                &pipeline.get_bind_group_layout(0),
                &resources,
            );
            gpu::dispatch(encoder, label, pipeline, &group, count, None);
        }
        self.readback.encode_copy(encoder, &self.result)
    }

    /// Call after submitting the encoder passed to [`Picker::encode`].
    pub fn submitted(&self) {
        self.readback.request();
    }

    /// `Some(answer)` once the GPU has answered: `Some(None)` when no vertex was near.
    pub fn poll(&self, context: &GpuContext) -> Option<Option<PickedVertex>> {
        let bytes = self.readback.try_take(context)?;
        let result: PickResult = bytemuck::pod_read_unaligned(&bytes);
        Some((result.vertex != u32::MAX).then(|| PickedVertex {
            vertex: result.vertex,
            position: Vec3::new(result.position[0], result.position[1], result.position[2]),
        }))
    }
}
