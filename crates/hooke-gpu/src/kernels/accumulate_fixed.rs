//! `accumulate_fixed.wgsl` and `resolve_fixed.wgsl`: scatter's accumulation by integer
//! `atomicAdd` of `round(f * scale)` (deterministic, and available on WebGPU), then a resolve
//! pass back to newtons. The scale keeps any vertex's sum below 2^31; a larger contribution is
//! clamped and flagged in the status.

use super::ScatterBuffers;
use crate::context::{GpuContext, GpuError};
use crate::gpu::{Kernel, zeroed};
use crate::model::vec4s;

#[derive(Debug)]
pub struct AccumulateFixed {
    accumulate: Kernel,
    resolve: Kernel,
    /// Per-vertex `vec4<i32>` sums (scratch).
    accumulators: wgpu::Buffer,
    vertex_count: u32,
}

impl AccumulateFixed {
    pub fn new(context: &GpuContext, buffers: &ScatterBuffers<'_>) -> Result<Self, GpuError> {
        let accumulators = zeroed(
            context,
            "fixed-point accumulators",
            vec4s(buffers.vertex_count as usize),
            wgpu::BufferUsages::COPY_DST,
        );
        let accumulate = Kernel::new(
            context,
            "accumulate atomic-fixed",
            super::ACCUMULATE_FIXED,
            "main",
            buffers.spring_count,
            |_| {
                vec![
                    (0, buffers.uniforms.as_entire_binding()),
                    (1, buffers.springs.as_entire_binding()),
                    (2, buffers.spring_forces.as_entire_binding()),
                    (3, accumulators.as_entire_binding()),
                    (4, buffers.status.as_entire_binding()),
                ]
            },
        )?;
        let resolve = Kernel::new(
            context,
            "resolve atomic-fixed",
            super::RESOLVE_FIXED,
            "main",
            buffers.vertex_count,
            |_| {
                vec![
                    (0, buffers.uniforms.as_entire_binding()),
                    (1, accumulators.as_entire_binding()),
                    (2, buffers.forces.as_entire_binding()),
                ]
            },
        )?;
        Ok(Self {
            accumulate,
            resolve,
            accumulators,
            vertex_count: buffers.vertex_count,
        })
    }

    /// Bytes of the accumulators.
    pub fn bytes(&self) -> u64 {
        vec4s(self.vertex_count as usize)
    }

    /// The accumulation pass (clearing the accumulators first).
    pub fn encode_accumulate(
        &self,
        encoder: &mut wgpu::CommandEncoder,
        timestamps: Option<wgpu::ComputePassTimestampWrites<'_>>,
    ) {
        encoder.clear_buffer(&self.accumulators, 0, None);
        self.accumulate.encode(encoder, 0, timestamps);
    }

    /// The resolve pass: integer sums back to newtons.
    pub fn encode_resolve(
        &self,
        encoder: &mut wgpu::CommandEncoder,
        timestamps: Option<wgpu::ComputePassTimestampWrites<'_>>,
    ) {
        self.resolve.encode(encoder, 0, timestamps);
    }
}

#[cfg(test)]
mod tests {
    use crate::kernels::testing::{accumulated, assert_close};
    use crate::methods::Accumulation;

    /// Fixed point rounds each spring's force to 1/scale newtons (about 2.5e-8 of the largest
    /// force per vertex here), well inside the float32 tolerance of the other accumulations.
    const TOLERANCE: f64 = 1e-5;

    #[test]
    fn fixed_point_atomics_sum_spring_forces_as_the_reference_does() {
        if let Some((actual, expected)) = accumulated(Accumulation::AtomicFixed) {
            assert_close(&actual, &expected, TOLERANCE, "atomic-fixed");
        }
    }
}
