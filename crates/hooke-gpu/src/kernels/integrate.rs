//! `integrate.wgsl`: the scatter methods' integration pass, damped Verlet (paper eq. 3-4) in
//! delta form (`verlet.wgsl`, which gather runs inside its force pass). Reads the current
//! positions and the per-vertex forces (plus the extra forces of a control), writes the next
//! positions and updates the deltas in place; records the first non-finite vertex.

use crate::context::{GpuContext, GpuError};
use crate::gpu::Kernel;
use crate::model::GpuModel;
use crate::state::GpuState;

#[derive(Debug)]
pub struct Integrate {
    pub kernel: Kernel,
}

impl Integrate {
    pub fn new(
        context: &GpuContext,
        model: &GpuModel,
        state: &GpuState,
        forces: &wgpu::Buffer,
        extra_forces: &wgpu::Buffer,
    ) -> Result<Self, GpuError> {
        let kernel = Kernel::new(
            context,
            "integrate",
            super::INTEGRATE,
            "main",
            model.uniforms.vertex_count,
            |current| {
                vec![
                    (0, model.uniform_buffer.as_entire_binding()),
                    (1, state.positions[current].as_entire_binding()),
                    (2, state.positions[1 - current].as_entire_binding()),
                    (3, state.deltas.as_entire_binding()),
                    (4, model.scales.as_entire_binding()),
                    (5, forces.as_entire_binding()),
                    (6, extra_forces.as_entire_binding()),
                    (7, state.status.as_entire_binding()),
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
    use crate::state::positions_to_vec4;

    /// float32 positions of order 1 m after a handful of operations: a few ulps.
    const TOLERANCE_M: f64 = 1e-6;

    #[test]
    fn integrate_takes_the_delta_form_verlet_step_of_the_reference() {
        let Some(context) = context() else { return };
        let (mut scene, state) = stretched_scene();
        scene.material.damping = 0.05;
        let n = scene.model.vertex_count();
        let model = GpuModel::new(&context, &scene.model, &scene.material, GpuMethod::Gather)
            .expect("model");
        let gpu_state = GpuState::new(&context, n);
        gpu_state.write(&context, &state);
        model.write_uniforms(&context);
        // Given forces (the springs' at this state) and extra forces (a point force each).
        let seen = as_gpu_sees(&state);
        let spring = reference_spring_forces(&scene.model, &seen.positions);
        let extra: Vec<DVec3> = (0..n)
            .map(|v| DVec3::new(0.0, 1e-3 * v as f64, 0.0))
            .collect();
        let upload = |label, values: &[DVec3]| {
            let buffer = zeroed(&context, label, vec4s(n), wgpu::BufferUsages::COPY_DST);
            context.queue.write_buffer(
                &buffer,
                0,
                bytemuck::cast_slice(&positions_to_vec4(values)),
            );
            buffer
        };
        let (forces, extra_forces) = (upload("forces", &spring), upload("extra", &extra));
        let integrate =
            Integrate::new(&context, &model, &gpu_state, &forces, &extra_forces).expect("kernel");
        let mut with_extra = model.uniforms;
        with_extra.has_extra = 1;
        context
            .queue
            .write_buffer(&model.uniform_buffer, 0, bytemuck::bytes_of(&with_extra));
        run(&context, |e| {
            integrate.kernel.encode(e, gpu_state.current, None)
        });
        let next = read_vec3s(&context, &gpu_state.positions[1 - gpu_state.current], n);
        let expected = expected_verlet_step(&scene, &seen, &spring, &extra);
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
