//! `accumulate_atomic_f32.wgsl` and `accumulate_fixed.wgsl`: scatter's atomic accumulations,
//! each spring's force computed and added at its ends in one pass, so no per-spring force
//! buffer exists. Float `atomicAdd` (needs SHADER_FLOAT32_ATOMIC; the summation order, and so
//! the rounding, varies from run to run), or integer `atomicAdd` of `round(f * scale)`
//! (deterministic, and available on WebGPU), whose sums stay integers in the per-vertex force
//! buffer for `integrate_fixed.wgsl` to read. The scale keeps any vertex's sum below 2^31; a
//! larger contribution is clamped and flagged in the status.
//!
//! On a structured mesh whose records never change ([`crate::GpuModel::stencil`]) the kernels
//! run per vertex over the stencil instead of per spring record: each vertex computes the
//! springs it owns (those whose kind points to a higher index), subtracts each at its far end
//! and stores their sum for its own end ([`AccumulateAtomic::own_sums`], which the
//! integration adds): 3 atomic adds a spring instead of 6. (Until 2026-12-02 it added that
//! sum atomically, 4 a spring; with the store, atomic-f32's step on lavapipe was faster in 6
//! and 7 of 7 paired runs at 256^2 and 512^2, by 6% and 4% median against median: see the
//! performance log.)

use super::ScatterBuffers;
use crate::context::{GpuContext, GpuError};
use crate::gpu::{Kernel, zeroed};
use crate::model::vec4s;
use crate::state::GpuState;

#[derive(Debug)]
pub struct AccumulateAtomic {
    kernel: Kernel,
    /// The per-vertex sums the kernel adds into, cleared before it runs.
    sums: wgpu::Buffer,
    /// Whether the kernel reads the stencil (per vertex) rather than the spring records.
    pub reads_stencil: bool,
    /// Over the stencil: per vertex the sum of the springs it owns (floats, or integers with
    /// fixed point), stored every step (not cleared, not added to `sums`).
    own_sums: Option<wgpu::Buffer>,
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
        let model = buffers.model;
        let stencil = model.stencil();
        let (entry_point, invocations) = match stencil {
            Some(_) => ("stencil", buffers.vertex_count),
            None => ("main", buffers.spring_count),
        };
        let own_sums = stencil.is_some().then(|| {
            let vertices = buffers.vertex_count as usize;
            let copy = wgpu::BufferUsages::COPY_SRC;
            zeroed(context, "own springs' sums", vec4s(vertices), copy)
        });
        let kernel = Kernel::new(
            context,
            label,
            source,
            entry_point,
            invocations,
            |current| {
                let mut resources = vec![
                    (0, model.uniforms_binding(current)),
                    (2, state.positions[current].as_entire_binding()),
                    (3, buffers.forces.as_entire_binding()),
                ];
                // Where a clamped fixed-point contribution is flagged.
                if fixed_point {
                    resources.push((4, buffers.status.as_entire_binding()));
                }
                match stencil {
                    // The masks travel in the integration scales.
                    Some(stencil) => resources.extend([
                        (5, model.scales.as_entire_binding()),
                        (6, stencil.kinds.as_entire_binding()),
                    ]),
                    None => resources.push((1, buffers.springs.as_entire_binding())),
                }
                if let Some(own_sums) = &own_sums {
                    resources.push((7, own_sums.as_entire_binding()));
                }
                resources
            },
        )?;
        Ok(Self {
            kernel,
            sums: buffers.forces.clone(),
            reads_stencil: stencil.is_some(),
            own_sums,
        })
    }

    /// Where the kernel stores each vertex's own springs' sum, for the integration to add
    /// to `sums`: over a stencil only.
    pub fn own_sums(&self) -> Option<&wgpu::Buffer> {
        self.own_sums.as_ref()
    }

    /// Clears the per-vertex sums and adds every spring's force, computed from the `current`
    /// positions, in.
    pub fn encode(
        &self,
        encoder: &mut wgpu::CommandEncoder,
        current: usize,
        timestamps: Option<wgpu::ComputePassTimestampWrites<'_>>,
    ) {
        encoder.clear_buffer(&self.sums, 0, None);
        self.kernel.encode(encoder, current, timestamps);
    }
}

#[cfg(test)]
mod tests {
    use hooke_core::scene::MeshSection;

    use crate::kernels::testing::{accumulated, assert_close, stretched, stretched_scene};
    use crate::methods::Accumulation;

    /// float32 spring forces summed in some order at the vertices, against float64 from the
    /// same float32 positions: a few ulps of the largest force.
    const FLOAT_TOLERANCE: f64 = 1e-5;

    /// Fixed point rounds each spring's force to 1/scale newtons (about 2.5e-8 of the largest
    /// force per vertex here), well inside the float32 tolerance of the other accumulations.
    const FIXED_TOLERANCE: f64 = 1e-5;

    /// A 13 x 11 grid, whose springs are a stencil.
    fn grid() -> (hooke_core::scene::Scene, hooke_core::State) {
        stretched(MeshSection::unit_grid(13, 11), 143)
    }

    /// The irregular mesh over its records; the grid over its stencil and over its records.
    fn check(accumulation: Accumulation, tolerance: f64) {
        for (scene, records, stencil) in [
            (stretched_scene(), false, false),
            (grid(), false, true),
            (grid(), true, false),
        ] {
            let Some(sums) = accumulated(accumulation, scene, records) else {
                return;
            };
            assert_eq!(sums.over_stencil, stencil, "{}", accumulation.name());
            let what = format!("{}, stencil {stencil}", accumulation.name());
            assert_close(&sums.actual, &sums.expected, tolerance, &what);
        }
    }

    #[test]
    fn float_atomics_sum_spring_forces_as_the_reference_does() {
        check(Accumulation::AtomicF32, FLOAT_TOLERANCE);
    }

    #[test]
    fn fixed_point_atomics_sum_spring_forces_as_the_reference_does() {
        check(Accumulation::AtomicFixed, FIXED_TOLERANCE);
    }

    /// Integer sums are exact: the stencil's per-vertex grouping gives the records' integers.
    #[test]
    fn fixed_point_sums_over_the_stencil_are_the_records_sums() {
        let sums = |records| accumulated(Accumulation::AtomicFixed, grid(), records);
        let (Some(stencil), Some(records)) = (sums(false), sums(true)) else {
            return;
        };
        assert!(stencil.over_stencil && !records.over_stencil);
        assert_eq!(stencil.actual, records.actual);
    }
}
