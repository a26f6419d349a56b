//! `accumulate_atomic_f32.wgsl` and `accumulate_fixed.wgsl`: scatter's atomic accumulations,
//! each spring's force computed and added at its ends in one pass, so no per-spring force
//! buffer exists. Float `atomicAdd` (needs SHADER_FLOAT32_ATOMIC; the summation order, and so
//! the rounding, varies from run to run), or integer `atomicAdd` of `round(f * scale)`
//! (deterministic, and available on WebGPU), whose sums stay integers in the per-vertex force
//! buffer for `integrate_fixed.wgsl` to read. The scale keeps any vertex's sum below 2^31; a
//! larger contribution is clamped and flagged in the status.

use super::ScatterBuffers;
use crate::context::{GpuContext, GpuError};
use crate::gpu::Kernel;
use crate::state::GpuState;

#[derive(Debug)]
pub struct AccumulateAtomic {
    kernel: Kernel,
}

impl AccumulateAtomic {
    /// Float atomics, or integer ones on fixed-point values when `fixed_point`.
    pub fn new(
        context: &GpuContext,
        buffers: &ScatterBuffers<'_>,
        state: &GpuState,
        fixed_point: bool,
    ) -> Result<Self, GpuError> {
        let (label, source) = if fixed_point {
            ("forces and atomic-fixed sums", super::ACCUMULATE_FIXED)
        } else {
            ("forces and atomic-f32 sums", super::ACCUMULATE_ATOMIC_F32)
        };
        let kernel = Kernel::new(
            context,
            label,
            source,
            "main",
            buffers.spring_count,
            |current| {
                let mut resources = vec![
                    (0, buffers.model.uniforms_binding(current)),
                    (1, buffers.springs.as_entire_binding()),
                    (2, state.positions[current].as_entire_binding()),
                    (3, buffers.forces.as_entire_binding()),
                ];
                // Where a clamped fixed-point contribution is flagged.
                if fixed_point {
                    resources.push((4, buffers.status.as_entire_binding()));
                }
                resources
            },
        )?;
        Ok(Self { kernel })
    }

    /// Clears the per-vertex forces (`forces`, the buffer given at construction) and adds
    /// every spring's force, computed from the `current` positions, in.
    pub fn encode(
        &self,
        encoder: &mut wgpu::CommandEncoder,
        forces: &wgpu::Buffer,
        current: usize,
        timestamps: Option<wgpu::ComputePassTimestampWrites<'_>>,
    ) {
        encoder.clear_buffer(forces, 0, None);
        self.kernel.encode(encoder, current, timestamps);
    }
}

#[cfg(test)]
mod tests {
    use crate::kernels::testing::{accumulated, assert_close};
    use crate::methods::Accumulation;

    /// float32 spring forces summed in some order at the vertices, against float64 from the
    /// same float32 positions: a few ulps of the largest force.
    const FLOAT_TOLERANCE: f64 = 1e-5;

    /// Fixed point rounds each spring's force to 1/scale newtons (about 2.5e-8 of the largest
    /// force per vertex here), well inside the float32 tolerance of the other accumulations.
    const FIXED_TOLERANCE: f64 = 1e-5;

    #[test]
    fn float_atomics_sum_spring_forces_as_the_reference_does() {
        if let Some((actual, expected)) = accumulated(Accumulation::AtomicF32) {
            assert_close(&actual, &expected, FLOAT_TOLERANCE, "atomic-f32");
        }
    }

    #[test]
    fn fixed_point_atomics_sum_spring_forces_as_the_reference_does() {
        if let Some((actual, expected)) = accumulated(Accumulation::AtomicFixed) {
            assert_close(&actual, &expected, FIXED_TOLERANCE, "atomic-fixed");
        }
    }
}
