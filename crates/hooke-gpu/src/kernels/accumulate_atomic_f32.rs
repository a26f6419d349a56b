//! `accumulate_atomic_f32.wgsl`: scatter's accumulation by float `atomicAdd` into the
//! per-vertex force buffer (needs SHADER_FLOAT32_ATOMIC; the summation order, and so the
//! rounding, varies from run to run).

use super::ScatterBuffers;
use crate::context::{GpuContext, GpuError};
use crate::gpu::Kernel;

#[derive(Debug)]
pub struct AccumulateAtomicF32 {
    kernel: Kernel,
}

impl AccumulateAtomicF32 {
    pub fn new(context: &GpuContext, buffers: &ScatterBuffers<'_>) -> Result<Self, GpuError> {
        let kernel = Kernel::new(
            context,
            "accumulate atomic-f32",
            super::ACCUMULATE_ATOMIC_F32,
            "main",
            buffers.spring_count,
            |_| {
                vec![
                    (0, buffers.uniforms.as_entire_binding()),
                    (1, buffers.springs.as_entire_binding()),
                    (2, buffers.spring_forces.as_entire_binding()),
                    (3, buffers.forces.as_entire_binding()),
                ]
            },
        )?;
        Ok(Self { kernel })
    }

    /// Clears `forces` (the buffer given at construction) and adds every spring's force in.
    pub fn encode(
        &self,
        encoder: &mut wgpu::CommandEncoder,
        forces: &wgpu::Buffer,
        timestamps: Option<wgpu::ComputePassTimestampWrites<'_>>,
    ) {
        encoder.clear_buffer(forces, 0, None);
        self.kernel.encode(encoder, 0, timestamps);
    }
}
