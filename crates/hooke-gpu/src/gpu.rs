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

/// Compiles a compute entry point (bind group layout derived from the shader).
pub fn compute_pipeline(
    context: &GpuContext,
    label: &str,
    source: &str,
    entry_point: &str,
) -> Result<wgpu::ComputePipeline, GpuError> {
    let scope = context
        .device
        .push_error_scope(wgpu::ErrorFilter::Validation);
    let module = context
        .device
        .create_shader_module(wgpu::ShaderModuleDescriptor {
            label: Some(label),
            source: wgpu::ShaderSource::Wgsl(source.into()),
        });
    let pipeline = context
        .device
        .create_compute_pipeline(&wgpu::ComputePipelineDescriptor {
            label: Some(label),
            layout: None,
            module: &module,
            entry_point: Some(entry_point),
            compilation_options: Default::default(),
            cache: None,
        });
    match pollster::block_on(scope.pop()) {
        Some(error) => Err(GpuError::Validation(format!("{label}: {error}"))),
        None => Ok(pipeline),
    }
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

/// Workgroups for `count` invocations as a 2D grid (one dimension holds at most 65535);
/// kernels flatten it back with `flat_index`.
pub fn workgroups(count: u32) -> (u32, u32) {
    let groups = count.div_ceil(WORKGROUP_SIZE).max(1);
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
    pass.set_pipeline(pipeline);
    pass.set_bind_group(0, bind_group, &[]);
    let (x, y) = workgroups(count);
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
