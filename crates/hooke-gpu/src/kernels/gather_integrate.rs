//! `gather_integrate.wgsl`: the point-centric (PCA) step in one pass. One invocation per
//! vertex, in valence-sorted order, sums the forces of its springs (paper eq. 1) from its CSR
//! row and integrates at once (`verlet.wgsl`, shared with the scatter methods' `integrate`).

use super::integrate::verlet_bindings;
use crate::context::{GpuContext, GpuError};
use crate::gpu::Kernel;
use crate::model::{GpuModel, GpuTopology};
use crate::state::GpuState;

#[derive(Debug)]
pub struct GatherIntegrate {
    pub kernel: Kernel,
}

impl GatherIntegrate {
    pub fn new(
        context: &GpuContext,
        model: &GpuModel,
        state: &GpuState,
        extra_forces: &wgpu::Buffer,
    ) -> Result<Self, GpuError> {
        let GpuTopology::Gather { rows, entries } = &model.topology else {
            return Err(GpuError::Validation(
                "the gather step needs the gather adjacency".into(),
            ));
        };
        let kernel = Kernel::new(
            context,
            "gather and integrate",
            super::GATHER_INTEGRATE,
            "main",
            model.uniforms.vertex_count,
            |current| {
                let mut resources = verlet_bindings(model, state, extra_forces, current);
                resources.push((5, rows.as_entire_binding()));
                resources.push((8, entries.as_entire_binding()));
                resources
            },
        )?;
        Ok(Self { kernel })
    }
}

#[cfg(test)]
mod tests {
    use glam::DVec3;

    use super::*;
    use crate::gpu::zeroed;
    use crate::kernels::testing::{
        assert_next_positions, context, damped_on_gpu, expected_verlet_step,
        reference_spring_forces, run,
    };
    use crate::model::vec4s;

    /// float32 positions of order 1 m after summing up to 10 springs and a handful of
    /// operations: a few ulps. (A spring left out moves its ends by millimetres here.)
    const TOLERANCE_M: f64 = 1e-6;

    #[test]
    fn one_pass_sums_each_vertex_springs_and_takes_the_reference_verlet_step() {
        let Some(context) = context() else { return };
        let (scene, seen, model, gpu_state) = damped_on_gpu(&context);
        let n = scene.model.vertex_count();
        let extra = zeroed(&context, "extra", vec4s(n), wgpu::BufferUsages::empty());
        let gather = GatherIntegrate::new(&context, &model, &gpu_state, &extra).expect("kernel");
        run(&context, |e| {
            gather.kernel.encode(e, gpu_state.current, None)
        });
        let springs = reference_spring_forces(&scene.model, &seen.positions);
        let expected = expected_verlet_step(&scene, &seen, &springs, &vec![DVec3::ZERO; n]);
        assert_next_positions(&context, &gpu_state, &expected, TOLERANCE_M);
    }
}
