//! Physics tests: analytic cases, the f64 reference as oracle, and CPU method agreement.
use glam::DVec3;
use hooke_core::diagnostics::energy;
use hooke_core::diagnostics::relative_l2;
use hooke_core::reference::ReferenceSolver;
use hooke_core::scene::{MeshSection, Scene};
use hooke_core::{
    Control, MassModel, Material, Model, ModelOptions, SimError, Solver, State, StiffnessModel,
    Wind,
};
use hooke_cpu::kernels::InstructionSet;
use hooke_cpu::layout::VertexOrder;
use hooke_cpu::{CpuOptions, CpuSolver, Method};
use hooke_testkit::{Broken, assert_bar_rejects_broken, benchmark_scene, reference, state_of};

fn cpu_solver(
    model: &Model,
    material: &Material,
    control: &Control,
    method: Method,
    threads: usize,
) -> CpuSolver {
    let options = CpuOptions {
        method,
        threads: Some(threads),
        ..Default::default()
    };
    let mut solver = CpuSolver::new(model, material, options).expect("cpu solver");
    solver.set_control(control).expect("control");
    solver
}

fn cpu(scene: &Scene, method: Method, threads: usize) -> CpuSolver {
    cpu_solver(
        &scene.model,
        &scene.material,
        &scene.control,
        method,
        threads,
    )
}

/// Every solver under test, the reference first, driven by `control`.
fn solvers_of(model: &Model, material: &Material, control: &Control) -> Vec<Box<dyn Solver>> {
    let mut reference = ReferenceSolver::new(model, material);
    reference.set_control(control).expect("control");
    vec![
        Box::new(reference),
        Box::new(cpu_solver(model, material, control, Method::Gather, 2)),
        Box::new(cpu_solver(model, material, control, Method::Scatter, 2)),
    ]
}

/// Every solver under test for a scene, driven by the scene's control.
fn all_solvers(scene: &Scene) -> Vec<Box<dyn Solver>> {
    solvers_of(&scene.model, &scene.material, &scene.control)
}

/// Every solver of a bare model under `material`, without control.
fn model_solvers(model: &Model, material: Material) -> Vec<Box<dyn Solver>> {
    solvers_of(model, &material, &Control::default())
}

fn grid_section(columns: u32, rows: u32) -> MeshSection {
    MeshSection::unit_grid(columns, rows)
}

fn irregular_section(vertices: u32) -> MeshSection {
    MeshSection::unit_irregular(vertices, 11)
}

fn two_masses(pinned: Vec<u32>, stretch: f64, k: f64, m: f64) -> Model {
    let options = ModelOptions {
        stiffness: StiffnessModel::Uniform(k),
        mass: MassModel::PerVertex(m),
        rest_length_scale: 1.0 / (1.0 + stretch),
        pinned,
    };
    Model::from_springs(
        vec![DVec3::ZERO, DVec3::X],
        vec![[0, 1]],
        vec![m, m],
        &options,
    )
    .expect("model")
}

/// Period of the spring's length oscillation, from the mean spacing of upward zero crossings of
/// its extension (linearly interpolated between steps).
fn measured_period(solver: &mut dyn Solver, model: &Model, dt: f64, steps: u32) -> f64 {
    let extension = |s: &dyn Solver| {
        let state = state_of(s);
        state.positions[0].distance(state.positions[1]) - model.rest_lengths[0]
    };
    let mut crossings = Vec::new();
    let mut previous = extension(solver);
    for n in 1..=steps {
        solver.step(1).expect("stable");
        let e = extension(solver);
        if previous < 0.0 && e >= 0.0 {
            crossings.push((f64::from(n) - 1.0 + previous / (previous - e)) * dt);
        }
        previous = e;
    }
    assert!(crossings.len() >= 3, "too few oscillations");
    (crossings[crossings.len() - 1] - crossings[0]) / (crossings.len() - 1) as f64
}

#[test]
fn single_spring_period_matches_two_pi_sqrt_m_eff_over_k() {
    let (k, m) = (40.0, 0.5);
    // Free pair: reduced mass m/2. One end pinned: the free mass m.
    for (pinned, m_eff) in [(vec![], m / 2.0), (vec![0], m)] {
        let model = two_masses(pinned, 0.01, k, m);
        let expected = 2.0 * std::f64::consts::PI * (m_eff / k).sqrt();
        let dt = expected / 2000.0;
        let material = Material {
            dt,
            gravity: DVec3::ZERO,
            ..Default::default()
        };
        for mut solver in model_solvers(&model, material) {
            let period = measured_period(solver.as_mut(), &model, dt, 12_000);
            // Verlet's period error is (w dt)^2 / 24 ~ 4e-7 here; crossing interpolation and
            // f32 rounding of a 1 cm amplitude stay well below 1e-4.
            let tolerance = 1e-4;
            assert!(
                (period / expected - 1.0).abs() < tolerance,
                "{}: period {period} vs {expected}",
                solver.describe()
            );
        }
    }
}

#[test]
fn free_fall_follows_verlet_closed_form_and_converges_to_g_t2_over_2() {
    let options = ModelOptions {
        stiffness: StiffnessModel::Uniform(1.0),
        mass: MassModel::PerVertex(1.0),
        rest_length_scale: 1.0,
        pinned: vec![],
    };
    let model = Model::from_springs(vec![DVec3::new(0.0, 2.0, 0.0)], vec![], vec![1.0], &options)
        .expect("model");
    let g = 9.81;
    for dt in [1e-3, 1e-4] {
        let material = Material {
            dt,
            ..Default::default()
        };
        let n = (0.2 / dt).round() as u32;
        for mut solver in model_solvers(&model, material) {
            solver.step(n).expect("stable");
            let fallen = 2.0 - state_of(solver.as_ref()).positions[0].y;
            let t = f64::from(n) * dt;
            // Starting at rest with x(-dt) = x(0), Verlet gives exactly g dt^2 n (n + 1) / 2,
            // which is g t^2 / 2 plus a start-up offset g t dt / 2 that vanishes with dt.
            let closed_form = g * dt * dt * f64::from(n) * f64::from(n + 1) / 2.0;
            // f32 solvers round x + d to half an ulp of 2 m (1.2e-7) each step, a random walk.
            let f32_rounding = 2.4e-7 * f64::from(n).sqrt();
            assert!(
                (fallen - closed_form).abs() < 1e-12 + f32_rounding,
                "{}",
                solver.describe()
            );
            assert!((fallen - g * t * t / 2.0 - g * t * dt / 2.0).abs() < 1e-9 + f32_rounding);
        }
    }
}

#[test]
fn energy_is_conserved_without_damping() {
    let mut scene = benchmark_scene(grid_section(12, 12), 144);
    scene.material.damping = 0.0;
    scene.material.dt = 0.3 * scene.max_stable_dt;
    let material = scene.material;
    for mut solver in all_solvers(&scene) {
        // Energy at step n with the central velocity (x_{n+1} - x_{n-1}) / 2dt, which Verlet
        // conserves up to bounded O(dt^2) oscillation without drift.
        let mut states: Vec<State> = vec![state_of(solver.as_ref())];
        let mut energies = Vec::new();
        for _ in 0..3000 {
            solver.step(1).expect("stable");
            states.push(state_of(solver.as_ref()));
            if states.len() == 3 {
                let mut central = states[1].clone();
                central.previous_positions = states[0].positions.clone();
                central.positions = states[1].positions.clone();
                let mut e = energy(&scene.model, &central, &material);
                let v2: f64 = (0..scene.model.vertex_count())
                    .map(|i| {
                        let v =
                            (states[2].positions[i] - states[0].positions[i]) / (2.0 * material.dt);
                        0.5 * scene.model.masses[i] * v.length_squared()
                    })
                    .sum();
                e.kinetic = v2;
                energies.push(e);
                states.remove(0);
            }
        }
        let e0 = energies[0].total();
        let swing = energies
            .iter()
            .map(|e| e.gravitational)
            .fold(f64::NEG_INFINITY, f64::max)
            - energies
                .iter()
                .map(|e| e.gravitational)
                .fold(f64::INFINITY, f64::min);
        let drift = energies
            .iter()
            .map(|e| (e.total() - e0).abs())
            .fold(0.0, f64::max);
        // The cloth converts about `swing` J between potential and kinetic energy; the
        // total may wobble by a small fraction of that (dt is 0.3 of the stability limit).
        assert!(
            drift < 0.01 * swing,
            "{}: drift {drift} J of swing {swing} J",
            solver.describe()
        );
    }
}

#[test]
fn pinned_points_do_not_move() {
    let scene = benchmark_scene(grid_section(10, 10), 100);
    for mut solver in all_solvers(&scene) {
        solver.step(300).expect("stable");
        let state = state_of(solver.as_ref());
        for (i, pinned) in scene.model.pinned.iter().enumerate() {
            if *pinned {
                let start = scene.model.initial_positions[i].as_vec3().as_dvec3();
                assert_eq!(state.positions[i], start, "{}", solver.describe());
            }
        }
    }
}

#[test]
fn hanging_cloth_pin_reactions_balance_its_weight() {
    let mut scene = benchmark_scene(grid_section(9, 9), 81);
    // Stiffer springs, and damping near critical for the slowest (pendulum-like) modes, so the
    // cloth settles to static equilibrium within the run.
    scene.model.stiffnesses.iter_mut().for_each(|k| *k *= 10.0);
    scene.material.damping = 0.1;
    scene.material.dt = 0.5 * hooke_core::stability::stability_limit(&scene.model, 0.1).max_dt;
    let weight = scene.model.total_mass() * scene.material.gravity;
    for (index, mut solver) in all_solvers(&scene).into_iter().enumerate() {
        solver.step(40_000).expect("stable");
        let state = state_of(solver.as_ref());
        let speed = (0..scene.model.vertex_count())
            .map(|i| state.velocity(i, scene.material.dt).length())
            .fold(0.0, f64::max);
        // f32 positions of order 1 m can only settle into a limit cycle of a few ulps per step.
        let settled = if index == 0 {
            1e-4
        } else {
            8.0 * f64::from(f32::EPSILON) / scene.material.dt
        };
        assert!(
            speed < settled,
            "{}: not settled, max speed {speed}",
            solver.describe()
        );
        let total = hooke_testkit::mean_pin_reaction(solver.as_mut(), &scene, 2000);
        assert!(
            (total + weight).length() < 1e-3 * weight.length(),
            "{}: reactions {total} vs weight {weight}",
            solver.describe()
        );
    }
}

/// The bar: after 100 steps of the benchmark workload, relative L2 error < 1e-5. The float32
/// CPU solvers score 1.6e-7 (float32 rounding). On the 48^2 grid a solver that never moves
/// scores 8.6e-2, one without springs 6.6e-3, one ignoring damping 3.1e-2 and the closest, 1%
/// too stiff, 2.1e-5; the tests check that every broken solver fails the bar.
const AGREEMENT_AFTER_100_STEPS: f64 = 1e-5;

#[test]
fn cpu_methods_match_reference_after_100_benchmark_steps() {
    for (mesh, vertices) in [
        (grid_section(48, 48), 48 * 48),
        (irregular_section(2000), 2000),
    ] {
        let scene = benchmark_scene(mesh, vertices);
        let mut reference = reference(&scene);
        reference.step(100).expect("stable");
        let expected = state_of(&reference).positions;
        let broken = Broken::scores(&scene, 100, &expected);
        assert_bar_rejects_broken(AGREEMENT_AFTER_100_STEPS, &broken, "cpu");
        for method in Method::ALL {
            let mut solver = cpu(&scene, method, 2);
            solver.step(100).expect("stable");
            let error = relative_l2(&state_of(&solver).positions, &expected);
            eprintln!(
                "{vertices} vertices, {}: relative L2 error {error:.2e}",
                solver.describe()
            );
            assert!(
                error < AGREEMENT_AFTER_100_STEPS,
                "{}: {error:e}",
                solver.describe()
            );
        }
    }
}

/// A model and parameters exercising everything: irregular mesh, per-spring stiffness,
/// area-lumped masses, wind, a drag and a point force.
fn everything_scene() -> Scene {
    everything_scene_of(700)
}

/// [`everything_scene`] on an irregular mesh of `vertices` vertices.
fn everything_scene_of(vertices: u32) -> Scene {
    let mut scene = benchmark_scene(irregular_section(vertices), vertices);
    let options = ModelOptions {
        stiffness: StiffnessModel::InverseRestLength(20.0),
        mass: MassModel::AreaDensity(0.2),
        rest_length_scale: 0.98,
        pinned: vec![0, 5],
    };
    scene.model = Model::from_mesh(&scene.mesh, &options).expect("model");
    scene.material.dt = 0.5 * hooke_core::stability::stability_limit(&scene.model, 0.0).max_dt;
    scene.material.damping = 0.001;
    scene.control.wind = Some(Wind {
        velocity: DVec3::new(1.0, 0.5, 2.0),
        coefficient: 0.3,
    });
    scene.control.point_forces = vec![hooke_core::PointForce {
        vertex: 9,
        force: DVec3::new(0.0, 0.5, 0.0),
    }];
    scene.control.drags = vec![hooke_core::Drag {
        vertices: vec![20, 21],
        target: DVec3::new(0.0, 0.3, 0.0),
        stiffness: 2.0,
    }];
    scene
}

#[test]
fn all_forces_match_reference() {
    let scene = everything_scene();
    let mut reference = reference(&scene);
    reference.step(200).expect("stable");
    let expected = state_of(&reference).positions;
    let broken = Broken::scores(&scene, 200, &expected);
    assert_bar_rejects_broken(AGREEMENT_AFTER_100_STEPS, &broken, "cpu, all forces");
    for method in Method::ALL {
        let mut solver = cpu(&scene, method, 2);
        solver.step(200).expect("stable");
        let error = relative_l2(&state_of(&solver).positions, &expected);
        assert!(
            error < AGREEMENT_AFTER_100_STEPS,
            "{}: {error:e}",
            solver.describe()
        );
    }
}

#[test]
fn gather_scatter_orders_and_thread_counts_are_bit_identical() {
    // About 6 vertex tasks and 4 spring tasks (1024 vertices and 4096 springs each), so 1, 2
    // and 3 threads really split the work differently.
    let scene = everything_scene_of(6000);
    let run = |method, order, threads| {
        let options = CpuOptions {
            method,
            threads: Some(threads),
            order,
            ..Default::default()
        };
        let mut solver = CpuSolver::new(&scene.model, &scene.material, options).expect("solver");
        solver.set_control(&scene.control).expect("control");
        solver.step(150).expect("stable");
        state_of(&solver)
    };
    let baseline = run(Method::Scatter, VertexOrder::Mesh, 1);
    for method in Method::ALL {
        // Auto sorts windows of this irregular mesh by valence and by later neighbours, so
        // that scatter's summing takes many rows whole.
        for order in [
            VertexOrder::Mesh,
            VertexOrder::Auto,
            VertexOrder::Spatial,
            VertexOrder::ValenceSorted,
        ] {
            for threads in [1, 2, 3] {
                assert!(
                    run(method, order, threads) == baseline,
                    "{method:?} {order:?} {threads} threads differs"
                );
            }
        }
    }
}

/// On an irregular mesh the force pass reads the positions as points, which the integration
/// writes for the next step. Replacing the state must replace them too: stepping on from a
/// state written over another gives the same bits as stepping on without the detour.
#[test]
fn a_written_state_replaces_the_positions_the_force_pass_reads() {
    let scene = everything_scene();
    for method in Method::ALL {
        let mut through = cpu(&scene, method, 2);
        through.step(20).expect("stable");
        let middle = state_of(&through);
        through.step(20).expect("stable");
        let mut detour = cpu(&scene, method, 2);
        detour.step(5).expect("stable");
        detour.write_state(&middle);
        detour.step(20).expect("stable");
        assert!(state_of(&detour) == state_of(&through), "{method:?}");
    }
}

#[test]
fn phased_step_equals_fused_step() {
    let scene = everything_scene();
    for method in Method::ALL {
        let mut fused = cpu(&scene, method, 2);
        let mut phased = cpu(&scene, method, 2);
        fused.step(50).expect("stable");
        for _ in 0..50 {
            let (times, _) = phased.step_timed().expect("stable");
            assert_eq!(
                times.force_accumulation.is_some(),
                method == Method::Scatter
            );
        }
        assert!(state_of(&fused) == state_of(&phased), "{method:?}");
    }
}

#[test]
fn blow_up_is_reported_with_step_and_vertex() {
    let mut scene = benchmark_scene(grid_section(8, 8), 64);
    scene.material.dt = 3.0 * scene.max_stable_dt;
    for mut solver in all_solvers(&scene) {
        let error = solver.step(100_000).expect_err("must blow up");
        let SimError::NonFinite { step, vertex } = error else {
            panic!("unexpected {error:?}");
        };
        assert!(step > 1 && step < 100_000);
        assert!(!scene.model.pinned[vertex]);
        assert_eq!(solver.steps_taken(), step, "{}", solver.describe());
    }
}

#[test]
fn avx2_and_portable_kernels_are_bit_identical() {
    let scene = everything_scene();
    let run = |method, instruction_set| {
        let options = CpuOptions {
            method,
            threads: Some(2),
            order: VertexOrder::Mesh,
            instruction_set,
        };
        let mut solver = CpuSolver::new(&scene.model, &scene.material, options).expect("solver");
        solver.set_control(&scene.control).expect("control");
        solver.step(100).expect("stable");
        state_of(&solver)
    };
    for method in Method::ALL {
        assert!(
            run(method, InstructionSet::Best) == run(method, InstructionSet::Portable),
            "{method:?}: {} differs from portable",
            InstructionSet::Best.resolved_name()
        );
    }
}

/// The benchmark's irregular mesh has one stiffness, which the gather's loop over point
/// offsets reads once per slice rather than per row (`everything_scene` has one per spring):
/// both methods, both instruction sets and every vertex order give the same bits there too.
#[test]
fn one_stiffness_on_an_irregular_mesh_gives_the_same_bits_on_every_path() {
    let scene = benchmark_scene(irregular_section(3000), 3000);
    let run = |method, order, instruction_set| {
        let options = CpuOptions {
            method,
            threads: Some(2),
            order,
            instruction_set,
        };
        let mut solver = CpuSolver::new(&scene.model, &scene.material, options).expect("solver");
        solver.set_control(&scene.control).expect("control");
        solver.step(100).expect("stable");
        state_of(&solver)
    };
    let baseline = run(Method::Scatter, VertexOrder::Mesh, InstructionSet::Portable);
    for method in Method::ALL {
        for order in [VertexOrder::Auto, VertexOrder::ValenceSorted] {
            for isa in [InstructionSet::Best, InstructionSet::Portable] {
                assert!(
                    run(method, order, isa) == baseline,
                    "{method:?} {order:?} {isa:?} differs"
                );
            }
        }
    }
}

/// The closest any vertex comes to the surfaces of the ball and the ground (negative: inside).
#[test]
fn cloth_dropped_on_a_ball_or_a_bar_never_enters_it_or_the_ground() {
    use hooke_testkit::{check_cloth_stays_out, cloth_onto_ball, cloth_onto_capsule};
    for scene in [cloth_onto_ball(), cloth_onto_capsule()] {
        for mut solver in all_solvers(&scene) {
            check_cloth_stays_out(solver.as_mut(), &scene, 1e-6);
        }
    }
}

#[test]
fn a_moving_ball_pushes_through_a_curtain_without_entering_it() {
    let scene = hooke_testkit::curtain_and_moving_ball();
    for mut solver in all_solvers(&scene) {
        hooke_testkit::check_curtain_pushed(solver.as_mut(), &scene, 1e-6);
    }
}

/// Steps until the folding cloth (Fig. 3 in small) has landed, folded and come to rest.
const FOLD_STEPS: u32 = 5000;

#[test]
fn self_collision_keeps_folded_layers_apart_on_every_solver() {
    use hooke_testkit::{folding_cloth, interpenetrating_pairs};
    let scene = folding_cloth();
    let mut without = cpu(&scene, Method::Gather, 2);
    without.set_self_collision(None).expect("off");
    without.step(FOLD_STEPS).expect("stable");
    let crossed = interpenetrating_pairs(&scene, &state_of(&without));
    // The scene must fold: without self-collision, layers pass into each other.
    assert!(crossed > 100, "only {crossed} pairs without self-collision");
    for mut solver in all_solvers(&scene) {
        solver.step(FOLD_STEPS).expect("stable");
        let kept = interpenetrating_pairs(&scene, &state_of(solver.as_ref()));
        assert!(
            kept * 20 < crossed,
            "{}: {kept} interpenetrating pairs with self-collision, {crossed} without",
            solver.describe()
        );
    }
}

#[test]
fn self_collision_steps_agree_with_the_reference_from_a_folded_state() {
    // Folded cloth is chaotic, so solvers are compared one step at a time from the same
    // crumpled state, one folded without self-collision so many pairs need pushing apart:
    // same keys, same sort, same pushes.
    let scene = hooke_testkit::folding_cloth();
    let folded = state_of(&folded_without_self_collision(&scene));
    let mut solvers = all_solvers(&scene);
    let mut states = Vec::new();
    for solver in &mut solvers {
        solver.write_state(&folded);
        solver.step(1).expect("stable");
        states.push(state_of(solver.as_ref()));
    }
    // The step must push pairs apart, or the comparison would say nothing about them.
    let mut plain = reference(&scene);
    plain.set_self_collision(None).expect("off");
    plain.write_state(&folded);
    plain.step(1).expect("stable");
    let pushed = state_of(&plain)
        .positions
        .iter()
        .zip(&states[0].positions)
        .filter(|(a, b)| a.distance(**b) > 1e-4)
        .count();
    assert!(
        pushed > 100,
        "only {pushed} vertices pushed by self-collision"
    );
    for (solver, state) in solvers.iter().zip(&states).skip(1) {
        let error = relative_l2(&state.positions, &states[0].positions);
        assert!(
            error < 1e-6,
            "{}: relative L2 {error:.2e}",
            solver.describe()
        );
    }
}

/// The folding cloth `scene` folded for [`FOLD_STEPS`] without self-collision: crumpled, with
/// many unjoined pairs too close.
fn folded_without_self_collision(scene: &Scene) -> CpuSolver {
    let mut folder = cpu(scene, Method::Gather, 2);
    folder.set_self_collision(None).expect("off");
    folder.step(FOLD_STEPS).expect("stable");
    folder
}

#[test]
fn a_phase_timed_step_times_the_self_collision_by_part() {
    // From the folding cloth's crumpled state, where the step must push pairs apart (the
    // test above): the proof runs, then passes sort and test windows.
    let scene = hooke_testkit::folding_cloth();
    let mut folder = folded_without_self_collision(&scene);
    let (times, _) = folder.step_timed().expect("stable");
    assert_eq!(times.self_collision, None, "no self-collision, no parts");
    let folded = state_of(&folder);
    let mut solver = cpu(&scene, Method::Gather, 2);
    solver.write_state(&folded);
    let (times, _) = solver.step_timed().expect("stable");
    let parts = times.self_collision.expect("parts");
    let zero = std::time::Duration::ZERO;
    assert!(
        parts.measuring > zero && parts.pairs > zero && parts.sorting > zero,
        "{parts:?}"
    );
    assert!(parts.window_tests > zero, "{parts:?}");
    assert!(parts.total() <= times.collision, "{parts:?} in {times:?}");
}

/// Self-collision's passes run on every thread of the pool, with the threads kept awake
/// between them (`selfcollide::awake`); which thread runs which task must not change a bit.
/// The bench's 256^2 sheet after 2,000 steps has enough vertices in contact that the sorts
/// and window tests split into several tasks (the folding cloth's 576 vertices make one).
#[test]
fn self_collision_steps_are_bit_identical_on_one_two_and_four_threads() {
    use hooke_core::selfcollide::SelfCollision;
    let mut scene = benchmark_scene(MeshSection::unit_grid(256, 256), 256 * 256);
    scene.model.collision.self_collision = Some(SelfCollision::for_model(&scene.model));
    let mut settler = cpu(&scene, Method::Gather, 2);
    settler.step(2000).expect("stable");
    let settled = state_of(&settler);
    let steps = 10;
    let mut first = None;
    for method in [Method::Gather, Method::Scatter] {
        for threads in [1, 2, 4] {
            let mut solver = cpu(&scene, method, threads);
            solver.write_state(&settled);
            solver.step(steps).expect("stable");
            let positions = state_of(&solver).positions;
            let first = first.get_or_insert_with(|| positions.clone());
            assert!(
                positions == *first,
                "{method:?} on {threads} threads differs from gather on 1"
            );
        }
    }
    // The steps must push many pairs apart, or the comparison says little about them.
    let mut plain = cpu(&scene, Method::Gather, 1);
    plain.set_self_collision(None).expect("off");
    plain.write_state(&settled);
    plain.step(steps).expect("stable");
    let moved = state_of(&plain)
        .positions
        .iter()
        .zip(first.as_ref().expect("stepped"))
        .filter(|(a, b)| a != b)
        .count();
    assert!(
        moved > 1000,
        "only {moved} vertices moved by self-collision"
    );
}

#[test]
fn a_ball_dropped_on_a_pinned_sheet_is_slowed_and_held_on_every_solver() {
    let scene = hooke_testkit::ball_onto_sheet();
    for mut solver in all_solvers(&scene) {
        hooke_testkit::check_ball_dropped_on_sheet(solver.as_mut(), &scene);
    }
}

#[test]
fn a_ball_leaving_the_numbers_is_reported_with_step_and_collider() {
    let scene = hooke_testkit::exploding_ball();
    for mut solver in all_solvers(&scene) {
        let error = solver.step(5).expect_err("the ball explodes");
        assert_eq!(
            error,
            SimError::BallNonFinite {
                step: 1,
                collider: 0
            },
            "{}",
            solver.describe()
        );
        assert!(error.to_string().contains("collider 0"));
    }
}

/// On an irregular mesh the force pass reads the positions as points, which the integration
/// writes for the next step; self-collision reads them too and moves its vertices in them as
/// in the axes. Stepping on gives the same bits as writing the state back after every step
/// (which has the solver copy the points from the axes afresh), with many vertices moved.
#[test]
fn self_collision_moves_the_points_an_irregular_mesh_reads() {
    use hooke_core::selfcollide::SelfCollision;
    let vertices = 3000;
    let mut scene = benchmark_scene(irregular_section(vertices), vertices);
    let config = SelfCollision::for_model(&scene.model);
    scene.model.collision.self_collision = Some(config);
    // Folded in two across x = 0, the folded half half a distance above the other.
    let lift = 0.5 * config.distance;
    let positions: Vec<DVec3> = scene
        .model
        .initial_positions
        .iter()
        .map(|p| {
            if p.x > 0.0 {
                DVec3::new(-p.x, p.y + lift, p.z)
            } else {
                *p
            }
        })
        .collect();
    let folded = State {
        previous_positions: positions.clone(),
        positions,
    };
    let steps = 10;
    for method in Method::ALL {
        let mut on = cpu(&scene, method, 2);
        on.write_state(&folded);
        on.step(steps).expect("stable");
        let mut written = cpu(&scene, method, 2);
        written.write_state(&folded);
        for _ in 0..steps {
            written.step(1).expect("stable");
            let state = state_of(&written);
            written.write_state(&state);
        }
        assert!(state_of(&on) == state_of(&written), "{method:?}");
        let mut plain = cpu(&scene, method, 2);
        plain.set_self_collision(None).expect("off");
        plain.write_state(&folded);
        plain.step(steps).expect("stable");
        let moved = state_of(&plain)
            .positions
            .iter()
            .zip(&state_of(&on).positions)
            .filter(|(a, b)| a != b)
            .count();
        assert!(moved > 500, "{method:?}: only {moved} vertices moved");
    }
}
