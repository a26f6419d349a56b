//! `gather_integrate.wgsl`: the point-centric (PCA) step in one pass. One invocation per
//! vertex, in valence-sorted order, sums the forces of its springs (paper eq. 1) from its CSR
//! row and integrates at once (`verlet.wgsl`, shared with the scatter methods' `integrate`).

use super::integrate::verlet_bindings;
use crate::context::{GpuContext, GpuError};
use crate::gpu::Kernel;
use crate::model::{GpuModel, GpuTopology, uniform_stiffness};
use crate::state::GpuState;

#[derive(Debug)]
pub struct GatherIntegrate {
    pub kernel: Kernel,
    /// Whether the kernel takes the stiffness from the uniforms (see [`GatherIntegrate::new`]).
    pub uniform_stiffness: bool,
}

impl GatherIntegrate {
    /// With `may_tear` false and every spring of the model at one stiffness, the kernel takes
    /// it from the uniforms instead of reading it from each entry: a third fewer bytes per
    /// entry (10% less time per step at 256^2 on lavapipe). Springs that can tear need the
    /// entries' stiffness, which tearing zeroes.
    pub fn new(
        context: &GpuContext,
        model: &GpuModel,
        state: &GpuState,
        extra_forces: &wgpu::Buffer,
        may_tear: bool,
    ) -> Result<Self, GpuError> {
        let GpuTopology::Gather { rows, entries } = &model.topology else {
            return Err(GpuError::Validation(
                "the gather step needs the gather adjacency".into(),
            ));
        };
        let uniform_stiffness = !may_tear && uniform_stiffness(&model.model).is_some();
        let kernel = Kernel::new(
            context,
            "gather and integrate",
            super::GATHER_INTEGRATE,
            if uniform_stiffness {
                "uniform_stiffness"
            } else {
                "main"
            },
            model.uniforms.vertex_count,
            |current| {
                let mut resources = verlet_bindings(model, state, extra_forces, current);
                resources.push((5, rows.as_entire_binding()));
                resources.push((8, entries.as_entire_binding()));
                resources
            },
        )?;
        Ok(Self {
            kernel,
            uniform_stiffness,
        })
    }
}

#[cfg(test)]
mod tests {
    use glam::DVec3;

    use super::*;
    use crate::gpu::zeroed;
    use crate::kernels::testing::{
        assert_next_positions, context, damped_on_gpu, expected_verlet_step, read_vec3s,
        reference_spring_forces, run,
    };
    use crate::methods::GpuMethod;
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
        let springs = reference_spring_forces(&scene.model, &seen.positions);
        let expected = expected_verlet_step(&scene, &seen, &springs, &vec![DVec3::ZERO; n]);
        let next = &gpu_state.positions[1 - gpu_state.current];
        let mut results = Vec::new();
        // Both entry points: the stiffness from each entry, and from the uniforms.
        for may_tear in [true, false] {
            // Each run updates the deltas in place: start both from the same state.
            gpu_state.write(&context, &seen);
            let gather = GatherIntegrate::new(&context, &model, &gpu_state, &extra, may_tear)
                .expect("kernel");
            assert_eq!(gather.uniform_stiffness, !may_tear);
            run(&context, |e| {
                gather.kernel.encode(e, gpu_state.current, None)
            });
            assert_next_positions(&context, &gpu_state, &expected, TOLERANCE_M);
            results.push(read_vec3s(&context, next, n));
        }
        assert_eq!(
            results[0], results[1],
            "the two entry points give the same bits"
        );
    }

    #[test]
    fn springs_of_different_stiffness_read_each_entry() {
        let Some(context) = context() else { return };
        let (mut scene, _, _, gpu_state) = damped_on_gpu(&context);
        scene.model.stiffnesses[0] *= 2.0;
        let model = GpuModel::new(&context, &scene.model, &scene.material, GpuMethod::Gather)
            .expect("model");
        let extra = zeroed(&context, "extra", vec4s(1), wgpu::BufferUsages::empty());
        let gather =
            GatherIntegrate::new(&context, &model, &gpu_state, &extra, false).expect("kernel");
        assert!(!gather.uniform_stiffness);
    }
}
