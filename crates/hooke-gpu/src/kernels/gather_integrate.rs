//! `gather_integrate.wgsl`: the point-centric (PCA) step in one pass. One invocation per
//! vertex, in valence-sorted order, sums the forces of its springs (paper eq. 1) from its CSR
//! row and integrates at once (`verlet.wgsl`, shared with the scatter methods' `integrate`).

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
                vec![
                    (0, model.uniform_buffer.as_entire_binding()),
                    (1, state.positions[current].as_entire_binding()),
                    (2, state.positions[1 - current].as_entire_binding()),
                    (3, state.deltas.as_entire_binding()),
                    (4, model.scales.as_entire_binding()),
                    (5, rows.as_entire_binding()),
                    (6, extra_forces.as_entire_binding()),
                    (7, state.status.as_entire_binding()),
                    (8, entries.as_entire_binding()),
                ]
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
        as_gpu_sees, context, expected_verlet_step, read_vec3s, reference_spring_forces, run,
        stretched_scene,
    };
    use crate::methods::GpuMethod;
    use crate::model::vec4s;

    /// float32 positions of order 1 m after summing up to 10 springs and a handful of
    /// operations: a few ulps. (A spring left out moves its ends by millimetres here.)
    const TOLERANCE_M: f64 = 1e-6;

    #[test]
    fn one_pass_sums_each_vertex_springs_and_takes_the_reference_verlet_step() {
        let Some(context) = context() else { return };
        let (mut scene, state) = stretched_scene();
        scene.material.damping = 0.05;
        let n = scene.model.vertex_count();
        let model = GpuModel::new(&context, &scene.model, &scene.material, GpuMethod::Gather)
            .expect("model");
        let gpu_state = GpuState::new(&context, n);
        gpu_state.write(&context, &state);
        model.write_uniforms(&context);
        let extra = zeroed(&context, "extra", vec4s(n), wgpu::BufferUsages::empty());
        let gather = GatherIntegrate::new(&context, &model, &gpu_state, &extra).expect("kernel");
        run(&context, |e| {
            gather.kernel.encode(e, gpu_state.current, None)
        });
        let seen = as_gpu_sees(&state);
        let springs = reference_spring_forces(&scene.model, &seen.positions);
        let expected = expected_verlet_step(&scene, &seen, &springs, &vec![DVec3::ZERO; n]);
        let next = read_vec3s(&context, &gpu_state.positions[1 - gpu_state.current], n);
        for v in 0..n {
            assert!(
                next[v].distance(expected[v]) < TOLERANCE_M,
                "vertex {v}: {} vs {}",
                next[v],
                expected[v]
            );
        }
    }
}
