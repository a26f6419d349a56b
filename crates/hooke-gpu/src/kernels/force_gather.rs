//! `force_gather.wgsl`: the point-centric (PCA) force pass. One invocation per vertex, in
//! valence-sorted order, sums the forces of its springs (paper eq. 1) from its CSR row into the
//! per-vertex force buffer.

use crate::context::{GpuContext, GpuError};
use crate::gpu::Kernel;
use crate::model::{GpuModel, GpuTopology};
use crate::state::GpuState;

#[derive(Debug)]
pub struct ForceGather {
    pub kernel: Kernel,
}

impl ForceGather {
    pub fn new(
        context: &GpuContext,
        model: &GpuModel,
        state: &GpuState,
        forces: &wgpu::Buffer,
    ) -> Result<Self, GpuError> {
        let GpuTopology::Gather {
            order,
            offsets,
            entries,
        } = &model.topology
        else {
            return Err(GpuError::Validation(
                "gather forces need the gather adjacency".into(),
            ));
        };
        let kernel = Kernel::new(
            context,
            "gather forces",
            super::FORCE_GATHER,
            "main",
            model.uniforms.vertex_count,
            |current| {
                vec![
                    (0, model.uniform_buffer.as_entire_binding()),
                    (1, state.positions[current].as_entire_binding()),
                    (2, order.as_entire_binding()),
                    (3, offsets.as_entire_binding()),
                    (4, entries.as_entire_binding()),
                    (5, forces.as_entire_binding()),
                ]
            },
        )?;
        Ok(Self { kernel })
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::gpu::zeroed;
    use crate::kernels::testing::{
        as_gpu_sees, assert_close, context, read_vec3s, reference_spring_forces, run,
        stretched_scene,
    };
    use crate::methods::GpuMethod;
    use crate::model::vec4s;

    /// float32 spring forces summed over up to 10 springs, against float64 from the same
    /// float32 positions: a few ulps of the largest force.
    const TOLERANCE: f64 = 1e-5;

    #[test]
    fn gather_sums_each_vertex_springs_as_the_reference_does() {
        let Some(context) = context() else { return };
        let (scene, state) = stretched_scene();
        let n = scene.model.vertex_count();
        let model = GpuModel::new(&context, &scene.model, &scene.material, GpuMethod::Gather)
            .expect("model");
        let gpu_state = GpuState::new(&context, n);
        gpu_state.write(&context, &state);
        model.write_uniforms(&context);
        let forces = zeroed(&context, "forces", vec4s(n), wgpu::BufferUsages::COPY_SRC);
        let gather = ForceGather::new(&context, &model, &gpu_state, &forces).expect("kernel");
        run(&context, |e| {
            gather.kernel.encode(e, gpu_state.current, None)
        });
        let expected = reference_spring_forces(&scene.model, &as_gpu_sees(&state).positions);
        assert_close(
            &read_vec3s(&context, &forces, n),
            &expected,
            TOLERANCE,
            "gather",
        );
    }
}
