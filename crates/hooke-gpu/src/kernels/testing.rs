//! Helpers for the kernels' own tests: a device, a small model stretched off its rest shape,
//! read-backs, and the reference's float64 spring forces to compare with.

use std::path::Path;

use glam::DVec3;
use hooke_core::diagnostics::spring_force_on_a;
use hooke_core::scene::{MeshSection, Scene, SceneFile};
use hooke_core::{Model, State};

use crate::context::GpuContext;
use crate::gpu::{read_back, zeroed};
use crate::kernels::ScatterBuffers;
use crate::kernels::accumulate_atomic::AccumulateAtomic;
use crate::kernels::accumulate_incidence::AccumulateIncidence;
use crate::kernels::force_springs::ForceSprings;
use crate::methods::{Accumulation, GpuMethod};
use crate::model::{GpuModel, vec4s};
use crate::state::GpuState;
pub use crate::test_context as context;

/// A 12 x 12 irregular cloth (valences 3..10) and a state in which every vertex is moved off
/// its rest place and moving, so every spring pulls or pushes.
pub fn stretched_scene() -> (Scene, State) {
    stretched(MeshSection::unit_irregular(144, 4), 144)
}

/// `mesh` (of `vertices` vertices) as the benchmark's cloth, stretched as [`stretched_scene`].
pub fn stretched(mesh: MeshSection, vertices: u32) -> (Scene, State) {
    let scene = SceneFile::benchmark(mesh, vertices)
        .build(Path::new("kernel test"), true)
        .expect("scene");
    let shake = |v: usize, k: f64| {
        let f = v as f64;
        DVec3::new(
            (f * 1.7 + k).sin(),
            (f * 0.9 + k).cos(),
            (f * 2.3 - k).sin(),
        ) * 0.01
    };
    let positions: Vec<DVec3> = scene
        .model
        .initial_positions
        .iter()
        .enumerate()
        .map(|(v, p)| *p + shake(v, 0.0))
        .collect();
    let previous_positions = positions
        .iter()
        .enumerate()
        .map(|(v, p)| *p - 0.1 * shake(v, 1.0))
        .collect();
    (
        scene,
        State {
            positions,
            previous_positions,
        },
    )
}

/// The stretched scene with damping 0.05, laid out for gather on the GPU with its state
/// written: the scene, the state as float32 holds it, the model and the state buffers.
pub fn damped_on_gpu(context: &GpuContext) -> (Scene, State, GpuModel, GpuState) {
    damped_on_gpu_from(context, stretched_scene())
}

/// [`damped_on_gpu`] of a scene and state of one's own.
pub fn damped_on_gpu_from(
    context: &GpuContext,
    (mut scene, state): (Scene, State),
) -> (Scene, State, GpuModel, GpuState) {
    scene.material.damping = 0.05;
    let n = scene.model.vertex_count();
    let model =
        GpuModel::new(context, &scene.model, &scene.material, GpuMethod::Gather).expect("model");
    let gpu_state = GpuState::new(context, n);
    gpu_state.write(context, &state);
    model.write_uniforms(context);
    (scene, as_gpu_sees(&state), model, gpu_state)
}

/// Asserts that the position buffer a step writes holds `expected`, within `tolerance` m.
pub fn assert_next_positions(
    context: &GpuContext,
    gpu_state: &GpuState,
    expected: &[DVec3],
    tolerance: f64,
) {
    let next = read_vec3s(
        context,
        &gpu_state.positions[1 - gpu_state.current],
        expected.len(),
    );
    for (v, (next, expected)) in next.iter().zip(expected).enumerate() {
        assert!(
            next.distance(*expected) < tolerance,
            "vertex {v}: {next} vs {expected}"
        );
    }
}

/// The next positions of the delta-form Verlet step (paper eq. 3-4) from `state` under spring
/// forces `springs` (rounded to float32, as the GPU holds them) plus `extra`, in float64:
/// `d' = (1 - c dt/m) d + F dt^2/m + g dt^2`, pinned vertices kept.
pub fn expected_verlet_step(
    scene: &Scene,
    state: &State,
    springs: &[DVec3],
    extra: &[DVec3],
) -> Vec<DVec3> {
    let (m, material) = (&scene.model, &scene.material);
    let dt = material.dt;
    (0..m.vertex_count())
        .map(|v| {
            let x = state.positions[v];
            if m.pinned[v] {
                return x;
            }
            let d = x - state.previous_positions[v];
            let force = springs[v].as_vec3().as_dvec3() + extra[v].as_vec3().as_dvec3();
            x + d * (1.0 - material.damping * dt / m.masses[v])
                + force * dt * dt / m.masses[v]
                + material.gravity * dt * dt
        })
        .collect()
}

/// `count` `vec4` values of `buffer`, as float64 xyz.
pub fn read_vec3s(context: &GpuContext, buffer: &wgpu::Buffer, count: usize) -> Vec<DVec3> {
    let bytes = read_back(context, &[(buffer, 16 * count as u64)]).expect("read back");
    let values: Vec<[f32; 4]> = bytemuck::pod_collect_to_vec(&bytes[0]);
    values
        .iter()
        .map(|v| DVec3::new(v[0].into(), v[1].into(), v[2].into()))
        .collect()
}

/// Each vertex's sum of spring forces in float64: the reference solver's arithmetic.
pub fn reference_spring_forces(model: &Model, positions: &[DVec3]) -> Vec<DVec3> {
    let mut forces = vec![DVec3::ZERO; model.vertex_count()];
    for (s, [a, b]) in model.spring_ends.iter().enumerate() {
        let (a, b) = (*a as usize, *b as usize);
        let force = spring_force_on_a(
            positions[a],
            positions[b],
            model.rest_lengths[s],
            model.stiffnesses[s],
        );
        forces[a] += force;
        forces[b] -= force;
    }
    forces
}

/// Asserts every vector is within `tolerance` times the largest expected one.
pub fn assert_close(actual: &[DVec3], expected: &[DVec3], tolerance: f64, what: &str) {
    let scale = expected.iter().map(|f| f.length()).fold(0.0, f64::max);
    assert!(scale > 0.0, "{what}: nothing to compare");
    for (v, (a, e)) in actual.iter().zip(expected).enumerate() {
        assert!(
            a.distance(*e) <= tolerance * scale,
            "{what}: vertex {v}: {a} vs {e} (scale {scale:e})"
        );
    }
}

/// Records `record` into one encoder, submits it and waits.
pub fn run(context: &GpuContext, record: impl FnOnce(&mut wgpu::CommandEncoder)) {
    let mut encoder = context
        .device
        .create_command_encoder(&wgpu::CommandEncoderDescriptor {
            label: Some("kernel test"),
        });
    record(&mut encoder);
    context.queue.submit([encoder.finish()]);
}

/// `state` as the GPU holds it: float32 positions and deltas, back in float64.
pub fn as_gpu_sees(state: &State) -> State {
    let positions: Vec<DVec3> = state
        .positions
        .iter()
        .map(|p| p.as_vec3().as_dvec3())
        .collect();
    let previous_positions = state
        .positions
        .iter()
        .zip(&state.previous_positions)
        .zip(&positions)
        .map(|((p, q), rounded)| *rounded - (*p - *q).as_vec3().as_dvec3())
        .collect();
    State {
        positions,
        previous_positions,
    }
}

/// Per-vertex sums of an accumulation in newtons, the reference's, and whether the kernel
/// ran over the model's stencil.
pub struct Accumulated {
    pub actual: Vec<DVec3>,
    pub expected: Vec<DVec3>,
    pub over_stencil: bool,
}

/// Spring forces, then `accumulation`, from a stretched `scene` and `state` (see
/// [`stretched`]), reading the spring records when `records` even where a stencil could serve.
/// `None` without a device, or without the feature the accumulation needs.
pub fn accumulated(
    accumulation: Accumulation,
    (scene, state): (Scene, State),
    records: bool,
) -> Option<Accumulated> {
    let context = context()?;
    if let Some((feature, _)) = accumulation.required_feature()
        && !context.has(feature)
    {
        return None;
    }
    let n = scene.model.vertex_count();
    let method = GpuMethod::Scatter(accumulation);
    let mut model = GpuModel::new(&context, &scene.model, &scene.material, method).expect("model");
    if records {
        model.let_records_change(&context).expect("records");
    }
    let over_stencil = model.stencil().is_some();
    let gpu_state = GpuState::new(&context, n);
    gpu_state.write(&context, &state);
    model.write_uniforms(&context);
    let copy = wgpu::BufferUsages::COPY_SRC | wgpu::BufferUsages::COPY_DST;
    let forces = zeroed(&context, "forces", vec4s(n), copy);
    let buffers = ScatterBuffers::new(&model, &forces, &gpu_state).expect("spring records");
    let current = gpu_state.current;
    let actual = match accumulation {
        Accumulation::Incidence => {
            let springs = ForceSprings::new(&context, &model, &gpu_state).expect("springs");
            let sum =
                AccumulateIncidence::new(&context, &scene.model, &buffers, &springs.spring_forces)
                    .expect("kernel");
            run(&context, |e| {
                springs.kernel.encode(e, current, None);
                sum.kernel.encode(e, current, None);
            });
            read_vec3s(&context, &forces, n)
        }
        Accumulation::AtomicF32 => {
            let sum = AccumulateAtomic::new(&context, &buffers, &gpu_state, false).expect("kernel");
            run(&context, |e| sum.encode(e, current, None));
            let far = read_vec3s(&context, &forces, n);
            // Over a stencil, each vertex's own springs' sum is stored apart.
            match sum.own_sums() {
                Some(own) => {
                    let own = read_vec3s(&context, own, n);
                    far.iter().zip(own).map(|(far, own)| *far + own).collect()
                }
                None => far,
            }
        }
        Accumulation::AtomicFixed => {
            let sum = AccumulateAtomic::new(&context, &buffers, &gpu_state, true).expect("kernel");
            run(&context, |e| sum.encode(e, current, None));
            // Integer sums, in units of 1 / fixed_scale newtons (as integrate_fixed.wgsl
            // reads them).
            let integers = |buffer| {
                let bytes = read_back(&context, &[(buffer, vec4s(n))]).expect("read back");
                bytemuck::pod_collect_to_vec::<u8, [i32; 4]>(&bytes[0])
            };
            let mut sums = integers(&forces);
            // Over a stencil, each vertex's own springs' sum is stored apart.
            if let Some(own) = sum.own_sums() {
                for (sum, own) in sums.iter_mut().zip(integers(own)) {
                    for axis in 0..3 {
                        sum[axis] = sum[axis].wrapping_add(own[axis]);
                    }
                }
            }
            let scale = model.uniforms.fixed_scale;
            sums.iter()
                .map(|q| DVec3::new(q[0] as f64, q[1] as f64, q[2] as f64) / f64::from(scale))
                .collect()
        }
        other => panic!("{} is not tested here", other.name()),
    };
    let expected = reference_spring_forces(&scene.model, &as_gpu_sees(&state).positions);
    Some(Accumulated {
        actual,
        expected,
        over_stencil,
    })
}
