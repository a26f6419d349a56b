//! The engine API: live edits act in place exactly as a rebuilt solver would, snapshots
//! continue a run bit for bit, and on the GPU a control or material change creates nothing.

use std::sync::Arc;

use glam::DVec3;
use hooke::{Control, Material, Simulation, SolverChoice};
use hooke_core::scene::Scene;
use hooke_core::{BallPush, Drag, Wind};
use hooke_cpu::{CpuOptions, Method};
use hooke_gpu::{Accumulation, GpuMethod, test_context};
use hooke_testkit::shipped_scene;

/// The solvers whose results are deterministic, so equal inputs give bit-identical states.
fn deterministic_choices(gpu: bool) -> Vec<SolverChoice> {
    let cpu = |method| {
        SolverChoice::Cpu(CpuOptions {
            method,
            ..Default::default()
        })
    };
    let mut choices = vec![
        SolverChoice::Reference,
        cpu(Method::Gather),
        cpu(Method::Scatter),
    ];
    if gpu {
        choices.push(SolverChoice::Gpu(GpuMethod::Gather));
        choices.push(SolverChoice::Gpu(GpuMethod::Scatter(
            Accumulation::Incidence,
        )));
        choices.push(SolverChoice::Gpu(GpuMethod::Scatter(
            Accumulation::AtomicFixed,
        )));
    }
    choices
}

/// A drag, wind and a push on the first dynamic ball: every kind of control.
fn busy_control(scene: &Scene) -> Control {
    let ball = scene
        .model
        .collision
        .colliders
        .iter()
        .position(|c| c.dynamics.is_some());
    Control {
        wind: Some(Wind {
            velocity: DVec3::new(2.0, 0.0, 1.0),
            coefficient: 0.4,
        }),
        drags: vec![Drag {
            vertices: vec![7, 8],
            target: DVec3::new(0.2, 1.5, 0.1),
            stiffness: 5.0,
        }],
        ball_pushes: ball
            .map(|collider| BallPush {
                collider,
                force: DVec3::new(1.0, 0.0, -0.5),
            })
            .into_iter()
            .collect(),
        ..scene.control.clone()
    }
}

/// A material with every field changed: smaller dt, more damping, other gravity, stiffer.
fn other_material(material: &Material) -> Material {
    Material {
        dt: 0.7 * material.dt,
        damping: material.damping + 0.002,
        gravity: DVec3::new(0.5, -7.0, 0.0),
        stiffness_scale: 1.5,
    }
}

#[test]
fn live_control_and_material_edits_equal_a_solver_built_with_them() {
    let context = test_context();
    let scene = shipped_scene("wind-and-balls.toml");
    let control = busy_control(&scene);
    let material = other_material(&scene.material);
    for choice in deterministic_choices(context.is_some()) {
        // Edited live after 40 steps...
        let mut live = Simulation::from_scene(&scene, choice, context.clone()).expect("builds");
        live.step(40).expect("stable");
        let snapshot = live.snapshot().expect("snapshot");
        live.set_control(control.clone()).expect("control");
        live.set_material(material).expect("material");
        live.step(60).expect("stable");
        // ...and built with the new values, then continued from the same snapshot.
        let mut built =
            Simulation::new(&scene.model, &material, choice, context.clone()).expect("builds");
        built.set_control(control.clone()).expect("control");
        built.restore(&snapshot).expect("restore");
        built.step(60).expect("stable");
        let (a, b) = (live.snapshot().expect("a"), built.snapshot().expect("b"));
        assert!(
            a == b,
            "{}: live edits differ from a rebuilt solver",
            choice.name()
        );
        // The edits did something: the same run without them ends elsewhere.
        let mut plain = Simulation::from_scene(&scene, choice, context.clone()).expect("builds");
        plain.step(100).expect("stable");
        assert!(
            plain.state().expect("state") != a.state,
            "{}: the edits changed nothing",
            choice.name()
        );
    }
}

#[test]
fn a_run_continued_from_a_snapshot_equals_the_uninterrupted_run() {
    let context = test_context();
    // Dynamic balls and wind; and a keyframed collider on a repeating path.
    for name in ["wind-and-balls.toml", "ball-through-curtain.toml"] {
        let scene = shipped_scene(name);
        for choice in deterministic_choices(context.is_some()) {
            let mut whole = Simulation::from_scene(&scene, choice, context.clone()).expect("ok");
            whole.step(200).expect("stable");
            let mut first = Simulation::from_scene(&scene, choice, context.clone()).expect("ok");
            first.step(100).expect("stable");
            let snapshot = first.snapshot().expect("snapshot");
            let mut second = Simulation::from_scene(&scene, choice, context.clone()).expect("ok");
            second.restore(&snapshot).expect("restore");
            assert_eq!(second.steps_taken(), 100);
            second.step(100).expect("stable");
            assert!(
                whole.snapshot().expect("a") == second.snapshot().expect("b"),
                "{name} {}: 100 + 100 steps differ from 200",
                choice.name()
            );
        }
    }
}

#[test]
fn gpu_control_material_and_solver_status_need_no_new_pipelines() {
    let Some(context) = test_context() else {
        return;
    };
    let scene = shipped_scene("wind-and-balls.toml");
    for method in [
        GpuMethod::Gather,
        GpuMethod::Scatter(Accumulation::Incidence),
        GpuMethod::Scatter(Accumulation::AtomicFixed),
        GpuMethod::Scatter(Accumulation::BlendR16f),
    ] {
        let choice = SolverChoice::Gpu(method);
        let mut simulation =
            Simulation::from_scene(&scene, choice, Some(Arc::clone(&context))).expect("builds");
        let (pipelines, reads) = (context.pipelines_created(), context.blocking_reads());
        let mut control = busy_control(&scene);
        let mut material = scene.material;
        for k in 0..30 {
            // A drag following the mouse, a wind slider, a stiffness slider.
            control.drags[0].target.x += 0.01;
            control.wind = control.wind.map(|w| Wind {
                coefficient: 0.1 * f64::from(k),
                ..w
            });
            material.stiffness_scale = 1.0 + 0.01 * f64::from(k);
            material.damping += 1e-4;
            material.dt *= 0.999;
            simulation.set_control(control.clone()).expect("control");
            simulation.set_material(material).expect("material");
        }
        assert_eq!(
            context.pipelines_created() - pipelines,
            0,
            "{}: pipelines created by live edits",
            choice.name()
        );
        assert_eq!(
            context.blocking_reads() - reads,
            0,
            "{}: blocking read-backs by live edits",
            choice.name()
        );
        simulation.step(20).expect("stable after the edits");
    }
}

#[test]
fn switching_solvers_carries_the_run_on() {
    let context = test_context();
    let scene = shipped_scene("wind-and-balls.toml");
    let reference = SolverChoice::Reference;
    let mut switched = Simulation::from_scene(&scene, reference, context.clone()).expect("ok");
    switched.step(50).expect("stable");
    let before = switched.snapshot().expect("snapshot");
    let cpu = SolverChoice::Cpu(CpuOptions::default());
    switched.switch_solver(cpu).expect("switch");
    assert_eq!(switched.choice(), cpu);
    let after = switched.snapshot().expect("snapshot");
    assert_eq!(after.steps_taken, 50);
    // float32 holds the float64 state to within its rounding.
    for (a, b) in after.state.positions.iter().zip(&before.state.positions) {
        assert!(a.distance(*b) < 1e-6, "{a} vs {b}");
    }
    for (a, b) in after.colliders.iter().zip(&before.colliders) {
        assert!(a.anchor().distance(b.anchor()) < 1e-6);
    }
    switched.step(50).expect("stable on the new solver");
}
