//! `integrate.wgsl`: the scatter methods' integration pass, damped Verlet (paper eq. 3-4) in
//! delta form (`verlet.wgsl`, which gather runs inside its force pass). Reads the current
//! positions and the per-vertex forces (plus the extra forces of a control), writes the next
//! positions and updates the deltas in place; records the first non-finite vertex. The
//! atomic-fixed accumulation's forces are integer sums, which `integrate_fixed.wgsl` reads.

use super::accumulate_incidence::IncidenceLayout;
use crate::context::{GpuContext, GpuError};
use crate::gpu::{Kernel, storage};
use crate::model::{GpuModel, bytes_of};
use crate::state::GpuState;

#[derive(Debug)]
pub struct Integrate {
    pub kernel: Kernel,
}

impl Integrate {
    /// Integrates under `forces`, integer sums with `fixed_point`; plus `own_sums` where an
    /// accumulation stored each vertex's own springs' sum apart (see
    /// [`super::accumulate_atomic::AccumulateAtomic::own_sums`]).
    pub fn new(
        context: &GpuContext,
        model: &GpuModel,
        state: &GpuState,
        (forces, own_sums): (&wgpu::Buffer, Option<&wgpu::Buffer>),
        extra_forces: &wgpu::Buffer,
        fixed_point: bool,
    ) -> Result<Self, GpuError> {
        let (label, source) = if fixed_point {
            ("integrate fixed-point sums", super::INTEGRATE_FIXED)
        } else {
            ("integrate", super::INTEGRATE)
        };
        let entry_point = match own_sums {
            Some(_) => "with_own_sums",
            None => "main",
        };
        let kernel = Kernel::new(
            context,
            label,
            source,
            entry_point,
            model.uniforms.vertex_count,
            |current| {
                let mut resources = verlet_bindings(model, state, extra_forces, current);
                resources.push((5, forces.as_entire_binding()));
                if let Some(own_sums) = own_sums {
                    resources.push((8, own_sums.as_entire_binding()));
                }
                resources
            },
        )?;
        Ok(Self { kernel })
    }

    /// The incidence accumulation of `spring_forces` fused with integration, over the table in
    /// rows of `width` entries (see [`IncidenceLayout::Rows`]); and the table's bytes.
    pub fn incidence_rows(
        context: &GpuContext,
        model: &GpuModel,
        state: &GpuState,
        (spring_forces, extra_forces): (&wgpu::Buffer, &wgpu::Buffer),
        width: u32,
    ) -> Result<(Self, u64), GpuError> {
        let entries = IncidenceLayout::Rows(width).entries(&model.model);
        let none = wgpu::BufferUsages::empty();
        let entries_buffer = storage(context, "incidence rows", &entries, none);
        let kernel = Kernel::with_constants(
            context,
            "sum incidence rows and integrate",
            (
                super::INTEGRATE_INCIDENCE,
                "main",
                &[("ROW_ENTRIES", f64::from(width))],
            ),
            model.uniforms.vertex_count,
            |current| {
                let mut resources = verlet_bindings(model, state, extra_forces, current);
                resources.push((8, spring_forces.as_entire_binding()));
                resources.push((9, entries_buffer.as_entire_binding()));
                resources
            },
        )?;
        Ok((Self { kernel }, bytes_of(&entries)))
    }
}

/// The bindings `verlet.wgsl` declares (0-4, 6, 7), for every kernel that integrates; each
/// adds its own force source at 5 and up.
pub fn verlet_bindings<'a>(
    model: &'a GpuModel,
    state: &'a GpuState,
    extra_forces: &'a wgpu::Buffer,
    current: usize,
) -> Vec<(u32, wgpu::BindingResource<'a>)> {
    vec![
        (0, model.uniforms_binding(current)),
        (1, state.positions[current].as_entire_binding()),
        (2, state.positions[1 - current].as_entire_binding()),
        (3, state.deltas.as_entire_binding()),
        (4, model.scales.as_entire_binding()),
        (6, extra_forces.as_entire_binding()),
        (7, state.status.as_entire_binding()),
    ]
}

#[cfg(test)]
mod tests {
    use glam::DVec3;

    use super::*;
    use crate::gpu::zeroed;
    use crate::kernels::ScatterBuffers;
    use crate::kernels::accumulate_incidence::AccumulateIncidence;
    use crate::kernels::force_springs::ForceSprings;
    use crate::kernels::testing::{
        assert_next_positions, context, damped_on_gpu, expected_verlet_step, read_vec3s,
        reference_spring_forces, run, stretched_scene,
    };
    use crate::methods::{Accumulation, GpuMethod};
    use crate::model::vec4s;
    use crate::state::positions_to_vec4;

    /// float32 positions of order 1 m after a handful of operations: a few ulps.
    const TOLERANCE_M: f64 = 1e-6;

    #[test]
    fn integrate_takes_the_delta_form_verlet_step_of_the_reference() {
        let Some(context) = context() else { return };
        let (scene, seen, mut model, gpu_state) = damped_on_gpu(&context);
        let n = scene.model.vertex_count();
        // Given forces (the springs' at this state) and extra forces (a point force each).
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
        let integrate = Integrate::new(
            &context,
            &model,
            &gpu_state,
            (&forces, None),
            &extra_forces,
            false,
        )
        .expect("kernel");
        model.uniforms.has_extra = 1;
        model.write_uniforms(&context);
        run(&context, |e| {
            integrate.kernel.encode(e, gpu_state.current, None)
        });
        let expected = expected_verlet_step(&scene, &seen, &spring, &extra);
        assert_next_positions(&context, &gpu_state, &expected, TOLERANCE_M);
    }

    #[test]
    fn incidence_rows_summed_while_integrating_step_as_the_separate_passes_do() {
        let Some(context) = context() else { return };
        let (mut scene, state) = stretched_scene();
        scene.material.damping = 0.05;
        let n = scene.model.vertex_count();
        let widest = IncidenceLayout::widest(&scene.model);
        // One step from the same state: spring forces, then the sums by offsets and the
        // integration pass, or the sums of rows padded to the widest vertex in the
        // integration pass. The next positions and deltas.
        let step = |rows: bool| {
            let method = GpuMethod::Scatter(Accumulation::Incidence);
            let model =
                GpuModel::new(&context, &scene.model, &scene.material, method).expect("model");
            let gpu_state = GpuState::new(&context, n);
            gpu_state.write(&context, &state);
            model.write_uniforms(&context);
            let scratch = |label| zeroed(&context, label, vec4s(n), wgpu::BufferUsages::empty());
            let (forces, extra) = (scratch("forces"), scratch("extra"));
            let springs = ForceSprings::new(&context, &model, &gpu_state).expect("springs");
            let current = gpu_state.current;
            if rows {
                let sums = (&springs.spring_forces, &extra);
                let (integrate, _) =
                    Integrate::incidence_rows(&context, &model, &gpu_state, sums, widest as u32)
                        .expect("kernel");
                run(&context, |e| {
                    springs.kernel.encode(e, current, None);
                    integrate.kernel.encode(e, current, None);
                });
            } else {
                let buffers = ScatterBuffers::new(&model, &forces, &gpu_state).expect("records");
                let spring_forces = &springs.spring_forces;
                let sum = AccumulateIncidence::new(&context, &scene.model, &buffers, spring_forces)
                    .expect("kernel");
                let integrate =
                    Integrate::new(&context, &model, &gpu_state, (&forces, None), &extra, false)
                        .expect("kernel");
                run(&context, |e| {
                    springs.kernel.encode(e, current, None);
                    sum.kernel.encode(e, current, None);
                    integrate.kernel.encode(e, current, None);
                });
            }
            let next = read_vec3s(&context, &gpu_state.positions[1 - current], n);
            (next, read_vec3s(&context, &gpu_state.deltas, n))
        };
        let (by_offsets, in_rows) = (step(false), step(true));
        assert!(by_offsets == in_rows, "padded rows change the step");
        let moved = by_offsets.0.iter().zip(&state.positions);
        assert!(moved.filter(|(a, b)| a.distance(**b) > 1e-6).count() > n / 2);
    }
}
