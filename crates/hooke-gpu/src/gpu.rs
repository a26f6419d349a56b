//! Small helpers over wgpu shared by the solver: buffers, pipelines, bind groups, dispatches.

use wgpu::util::DeviceExt;

use crate::GpuError;
use crate::context::GpuContext;

/// Invocations per workgroup of every compute kernel (`WORKGROUP_SIZE` in WGSL).
pub const WORKGROUP_SIZE: u32 = 64;

/// A storage buffer holding `data` (at least 16 bytes: zero-sized bindings are invalid).
pub fn storage<T: bytemuck::Pod>(
    context: &GpuContext,
    label: &str,
    data: &[T],
    extra: wgpu::BufferUsages,
) -> wgpu::Buffer {
    let bytes: &[u8] = bytemuck::cast_slice(data);
    let mut contents = bytes.to_vec();
    contents.resize(bytes.len().max(16), 0);
    context
        .device
        .create_buffer_init(&wgpu::util::BufferInitDescriptor {
            label: Some(label),
            contents: &contents,
            usage: wgpu::BufferUsages::STORAGE | extra,
        })
}

/// A uniform buffer holding `value`.
pub fn uniform<T: bytemuck::Pod>(context: &GpuContext, value: &T) -> wgpu::Buffer {
    context
        .device
        .create_buffer_init(&wgpu::util::BufferInitDescriptor {
            label: Some("uniforms"),
            contents: bytemuck::bytes_of(value),
            usage: wgpu::BufferUsages::UNIFORM,
        })
}

/// A zeroed storage buffer of `bytes` bytes (at least 16).
pub fn zeroed(
    context: &GpuContext,
    label: &str,
    bytes: u64,
    extra: wgpu::BufferUsages,
) -> wgpu::Buffer {
    context.device.create_buffer(&wgpu::BufferDescriptor {
        label: Some(label),
        size: bytes.max(16),
        usage: wgpu::BufferUsages::STORAGE | extra,
        mapped_at_creation: false,
    })
}

/// Fails with a clear message if `bytes` exceed what one storage binding may hold.
pub fn check_binding_size(
    context: &GpuContext,
    what: &'static str,
    bytes: u64,
) -> Result<(), GpuError> {
    let limit = context.device.limits().max_storage_buffer_binding_size;
    if bytes > limit {
        return Err(GpuError::TooLarge {
            what,
            needed: bytes,
            limit,
            adapter: context.info.name.clone(),
        });
    }
    Ok(())
}

/// Compiles a compute entry point (bind group layout derived from the shader); counted in
/// [`GpuContext::pipelines_created`].
pub fn compute_pipeline(
    context: &GpuContext,
    label: &str,
    source: &str,
    entry_point: &str,
) -> Result<wgpu::ComputePipeline, GpuError> {
    compute_pipeline_with(context, label, source, entry_point, &[])
}

/// [`compute_pipeline`] with values for the shader's pipeline-overridable constants (WGSL
/// `override`s), by name.
pub fn compute_pipeline_with(
    context: &GpuContext,
    label: &str,
    source: &str,
    entry_point: &str,
    constants: &[(&str, f64)],
) -> Result<wgpu::ComputePipeline, GpuError> {
    context.note_pipeline();
    validated(context, label, || {
        let module = shader_module(context, label, source);
        context
            .device
            .create_compute_pipeline(&wgpu::ComputePipelineDescriptor {
                label: Some(label),
                layout: None,
                module: &module,
                entry_point: Some(entry_point),
                compilation_options: wgpu::PipelineCompilationOptions {
                    constants,
                    ..Default::default()
                },
                cache: None,
            })
    })
}

/// Runs `create` under a validation error scope and returns its error, named by `what`, as a
/// value. A browser cannot wait for the scope (the answer comes from its event loop), so on
/// wasm errors go to the device's uncaptured-error handler instead and come back from the next
/// [`GpuContext::take_error`], which the page checks every frame.
pub fn validated<T>(
    context: &GpuContext,
    what: &str,
    create: impl FnOnce() -> T,
) -> Result<T, GpuError> {
    #[cfg(not(target_arch = "wasm32"))]
    {
        let scope = context
            .device
            .push_error_scope(wgpu::ErrorFilter::Validation);
        let created = create();
        match pollster::block_on(scope.pop()) {
            Some(error) => Err(GpuError::Validation(format!("{what}: {error}"))),
            None => Ok(created),
        }
    }
    #[cfg(target_arch = "wasm32")]
    {
        let _ = (context, what);
        Ok(create())
    }
}

/// Creates a render pipeline, counted in [`GpuContext::pipelines_created`], with validation
/// errors returned as values.
pub fn render_pipeline(
    context: &GpuContext,
    descriptor: &wgpu::RenderPipelineDescriptor<'_>,
) -> Result<wgpu::RenderPipeline, GpuError> {
    context.note_pipeline();
    validated(
        context,
        descriptor.label.unwrap_or("render pipeline"),
        || context.device.create_render_pipeline(descriptor),
    )
}

/// A shader module from WGSL source.
pub fn shader_module(context: &GpuContext, label: &str, source: &str) -> wgpu::ShaderModule {
    context
        .device
        .create_shader_module(wgpu::ShaderModuleDescriptor {
            label: Some(label),
            source: wgpu::ShaderSource::Wgsl(source.into()),
        })
}

/// A bind group for group 0 of `layout` with `(binding, resource)` pairs.
pub fn bind_group(
    context: &GpuContext,
    label: &str,
    layout: &wgpu::BindGroupLayout,
    resources: &[(u32, wgpu::BindingResource<'_>)],
) -> wgpu::BindGroup {
    let entries: Vec<wgpu::BindGroupEntry<'_>> = resources
        .iter()
        .map(|(binding, resource)| wgpu::BindGroupEntry {
            binding: *binding,
            resource: resource.clone(),
        })
        .collect();
    context
        .device
        .create_bind_group(&wgpu::BindGroupDescriptor {
            label: Some(label),
            layout,
            entries: &entries,
        })
}

/// A compute entry point bound once per position buffer (the two swap roles every step), run
/// over a fixed number of invocations: the shape of every kernel of a step. A kernel that reads
/// no positions gets the same resources for both.
#[derive(Debug)]
pub struct Kernel {
    label: &'static str,
    pipeline: wgpu::ComputePipeline,
    /// By which position buffer is current.
    groups: [wgpu::BindGroup; 2],
    count: u32,
}

impl Kernel {
    /// Compiles `entry_point` of `source` and binds `resources(current)` for both position
    /// buffers; `count` invocations per dispatch.
    pub fn new<'a>(
        context: &GpuContext,
        label: &'static str,
        source: &str,
        entry_point: &str,
        count: u32,
        resources: impl Fn(usize) -> Vec<(u32, wgpu::BindingResource<'a>)>,
    ) -> Result<Self, GpuError> {
        Self::with_constants(context, label, (source, entry_point, &[]), count, resources)
    }

    /// [`Kernel::new`] with values for the shader's `override`s, by name.
    pub fn with_constants<'a>(
        context: &GpuContext,
        label: &'static str,
        (source, entry_point, constants): (&str, &str, &[(&str, f64)]),
        count: u32,
        resources: impl Fn(usize) -> Vec<(u32, wgpu::BindingResource<'a>)>,
    ) -> Result<Self, GpuError> {
        let pipeline = compute_pipeline_with(context, label, source, entry_point, constants)?;
        let layout = pipeline.get_bind_group_layout(0);
        let groups = [0, 1].map(|current| bind_group(context, label, &layout, &resources(current)));
        Ok(Self {
            label,
            pipeline,
            groups,
            count,
        })
    }

    /// One compute pass of the kernel, with `current` the current position buffer.
    pub fn encode(
        &self,
        encoder: &mut wgpu::CommandEncoder,
        current: usize,
        timestamps: Option<wgpu::ComputePassTimestampWrites<'_>>,
    ) {
        dispatch(
            encoder,
            self.label,
            &self.pipeline,
            &self.groups[current],
            self.count,
            timestamps,
        );
    }

    /// The kernel recorded into an open pass.
    pub fn encode_in(&self, pass: &mut wgpu::ComputePass<'_>, current: usize) {
        dispatch_in(pass, &self.pipeline, &self.groups[current], self.count);
    }
}

/// Workgroups for `count` invocations as a 2D grid (one dimension holds at most 65535);
/// kernels flatten it back with `flat_index`.
pub fn workgroups(count: u32) -> (u32, u32) {
    grid(count.div_ceil(WORKGROUP_SIZE))
}

/// `groups` workgroups (at least one) as a 2D grid, for kernels of their own workgroup size
/// that number their workgroups (`block_index` in `digits.wgsl`).
fn grid(groups: u32) -> (u32, u32) {
    let groups = groups.max(1);
    let rows = groups.div_ceil(65_535);
    (groups.div_ceil(rows), rows)
}

/// Records one compute pass running `pipeline` over `count` invocations.
pub fn dispatch(
    encoder: &mut wgpu::CommandEncoder,
    label: &str,
    pipeline: &wgpu::ComputePipeline,
    bind_group: &wgpu::BindGroup,
    count: u32,
    timestamp_writes: Option<wgpu::ComputePassTimestampWrites<'_>>,
) {
    let mut pass = encoder.begin_compute_pass(&wgpu::ComputePassDescriptor {
        label: Some(label),
        timestamp_writes,
    });
    dispatch_in(&mut pass, pipeline, bind_group, count);
}

/// Records `pipeline` over `count` invocations into an open pass (dispatches within a pass
/// see each other's writes, so a chain of kernels can share one pass and one timestamp pair).
pub fn dispatch_in(
    pass: &mut wgpu::ComputePass<'_>,
    pipeline: &wgpu::ComputePipeline,
    bind_group: &wgpu::BindGroup,
    count: u32,
) {
    dispatch_groups_in(pass, pipeline, bind_group, count.div_ceil(WORKGROUP_SIZE));
}

/// Records `pipeline` over `groups` workgroups (of whatever size its shader declares) into an
/// open compute pass.
pub fn dispatch_groups_in(
    pass: &mut wgpu::ComputePass<'_>,
    pipeline: &wgpu::ComputePipeline,
    bind_group: &wgpu::BindGroup,
    groups: u32,
) {
    pass.set_pipeline(pipeline);
    pass.set_bind_group(0, bind_group, &[]);
    let (x, y) = grid(groups);
    pass.dispatch_workgroups(x, y, 1);
}

/// Maps `buffer` for reading, waiting for the GPU (counted in `GpuContext::blocking_reads`).
pub fn map_blocking(context: &GpuContext, buffer: &wgpu::Buffer) -> Result<(), GpuError> {
    context.note_blocking_read();
    let (sender, receiver) = std::sync::mpsc::channel();
    buffer
        .slice(..)
        .map_async(wgpu::MapMode::Read, move |result| {
            let _ = sender.send(result);
        });
    context
        .device
        .poll(wgpu::PollType::wait_indefinitely())
        .map_err(|e| GpuError::ReadBack(e.to_string()))?;
    receiver
        .recv()
        .map_err(|e| GpuError::ReadBack(e.to_string()))?
        .map_err(|e| GpuError::ReadBack(e.to_string()))?;
    context.take_error()
}

/// Copies `bytes` of `source` into a mappable buffer, waits, and returns them.
pub fn read_back(
    context: &GpuContext,
    sources: &[(&wgpu::Buffer, u64)],
) -> Result<Vec<Vec<u8>>, GpuError> {
    let staging = copy_to_staging(context, sources);
    map_blocking(context, &staging)?;
    let view = staging
        .slice(..)
        .get_mapped_range()
        .map_err(|e| GpuError::ReadBack(e.to_string()))?;
    let mut out = Vec::with_capacity(sources.len());
    let mut offset = 0usize;
    for (_, bytes) in sources {
        out.push(view[offset..offset + *bytes as usize].to_vec());
        offset += *bytes as usize;
    }
    drop(view);
    staging.unmap();
    Ok(out)
}

/// Records and submits copies of `bytes` of each source, one after another, into a new
/// mappable buffer. Mapping it is the caller's: waited for natively ([`read_back`]), awaited in a
/// browser.
pub fn copy_to_staging(context: &GpuContext, sources: &[(&wgpu::Buffer, u64)]) -> wgpu::Buffer {
    let total: u64 = sources.iter().map(|(_, bytes)| *bytes).sum();
    let staging = context.device.create_buffer(&wgpu::BufferDescriptor {
        label: Some("read-back staging"),
        size: total.max(16),
        usage: wgpu::BufferUsages::MAP_READ | wgpu::BufferUsages::COPY_DST,
        mapped_at_creation: false,
    });
    let mut encoder = context
        .device
        .create_command_encoder(&wgpu::CommandEncoderDescriptor {
            label: Some("read back"),
        });
    let mut offset = 0;
    for (buffer, bytes) in sources {
        encoder.copy_buffer_to_buffer(buffer, 0, &staging, offset, *bytes);
        offset += bytes;
    }
    context.queue.submit([encoder.finish()]);
    staging
}

/// The frame's texture of `surface`, or `None` when this frame should be skipped (timed out,
/// occluded, or the surface had to be configured again).
pub fn current_texture(
    context: &GpuContext,
    surface: &wgpu::Surface<'_>,
    config: &wgpu::SurfaceConfiguration,
) -> Option<wgpu::SurfaceTexture> {
    match surface.get_current_texture() {
        wgpu::CurrentSurfaceTexture::Success(t) | wgpu::CurrentSurfaceTexture::Suboptimal(t) => {
            Some(t)
        }
        wgpu::CurrentSurfaceTexture::Timeout | wgpu::CurrentSurfaceTexture::Occluded => None,
        _ => {
            surface.configure(&context.device, config);
            None
        }
    }
}

/// `vertex_count + 1` offsets, then each vertex's triangle indices.
pub(crate) fn vertex_triangle_lists(vertex_count: usize, triangles: &[[u32; 3]]) -> Vec<u32> {
    let mut offsets = vec![0u32; vertex_count + 1];
    for t in triangles {
        for &v in t {
            offsets[v as usize + 1] += 1;
        }
    }
    for v in 0..vertex_count {
        offsets[v + 1] += offsets[v];
    }
    let mut cursor = offsets.clone();
    offsets.resize(vertex_count + 1 + 3 * triangles.len(), 0);
    for (index, t) in triangles.iter().enumerate() {
        for &v in t {
            offsets[vertex_count + 1 + cursor[v as usize] as usize] = index as u32;
            cursor[v as usize] += 1;
        }
    }
    offsets
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn workgroup_grid_covers_every_invocation_within_limits() {
        for count in [1u32, 63, 64, 65, 65_535 * 64, 65_535 * 64 + 1, 50_000_000] {
            let (x, y) = workgroups(count);
            assert!(x <= 65_535 && y <= 65_535, "{count}");
            assert!(
                u64::from(x) * u64::from(y) * 64 >= u64::from(count),
                "{count}"
            );
        }
    }
}
