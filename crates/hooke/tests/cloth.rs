//! Cloth features on every solver, against the float64 reference: bending springs.

use std::sync::Arc;

use glam::DVec3;
use hooke::{Simulation, SolverChoice};
use hooke_core::State;
use hooke_core::diagnostics::relative_l2;
use hooke_core::scene::Scene;
use hooke_cpu::{CpuOptions, Method};
use hooke_gpu::{Accumulation, GpuContext, GpuMethod, test_context, wgpu};
use hooke_testkit::scene_from_text;

/// Every float32 solver: CPU gather and scatter, and every GPU method when there is a GPU but
/// blend-rgba8, which sums forces in 8-bit fixed point (the paper's precision finding) and
/// loses these light scenes altogether (`hooke-gpu`'s tests hold it to its own bar).
fn float32_choices(gpu: bool) -> Vec<SolverChoice> {
    let cpu = |method| {
        SolverChoice::Cpu(CpuOptions {
            method,
            ..Default::default()
        })
    };
    let mut choices = vec![cpu(Method::Gather), cpu(Method::Scatter)];
    if gpu {
        choices.extend(
            GpuMethod::all()
                .into_iter()
                .filter(|m| *m != GpuMethod::Scatter(Accumulation::BlendRgba8))
                .map(SolverChoice::Gpu),
        );
    }
    choices
}

fn build(text: &str) -> Scene {
    scene_from_text(text, "test.toml")
}

/// A strip of tissue (1 g) 0.6 m long and 0.1 m wide along x, clamped by its first two
/// columns of vertices, hanging under gravity; with bending springs when `bending` is given
/// (N/m). Distance-2 springs resist a bend only to third order in its angle, so even stiff
/// ones hold the strip up a little: how much is what the reference says.
fn cantilever(bending: Option<f64>) -> Scene {
    let bending = bending.map_or(String::new(), |k| format!("[bending]\nstiffness = {k}\n"));
    build(&format!(
        r#"
[mesh]
generator = "grid"
resolution = [10, 3]
size = [0.6, 0.1]

[material]
mass = {{ total = 0.001 }}
stiffness = 400.0
damping = 0.0002

[pins]
boxes = [{{ min = [-1, -1, -1], max = [-0.23, 1, 1] }}]

{bending}"#
    ))
}

/// How far the strip's free end hangs below its clamp, m.
fn sag(state: &State) -> f64 {
    let tip = state
        .positions
        .iter()
        .map(|p| p.y)
        .fold(f64::INFINITY, f64::min);
    -tip
}

/// The state after `seconds` of `scene` on `choice`, from `start` or from rest.
fn run(
    scene: &Scene,
    choice: SolverChoice,
    context: &Option<Arc<GpuContext>>,
    seconds: f64,
    start: Option<&State>,
) -> State {
    let mut simulation = Simulation::from_scene(scene, choice, context.clone()).expect("solver");
    if let Some(start) = start {
        simulation.set_state(start);
    }
    simulation
        .step((seconds / scene.material.dt).round() as u32)
        .expect("stable");
    simulation.state().expect("state")
}

#[test]
fn bending_springs_hold_a_cantilever_up_as_the_reference_does() {
    let context = test_context();
    let (limp, stiff) = (cantilever(None), cantilever(Some(400.0)));
    assert!(stiff.model.bending_springs > 0);
    let seconds = 1.0;
    let reference = |scene| run(scene, SolverChoice::Reference, &context, seconds, None);
    let (limp_sag, stiff_state) = (sag(&reference(&limp)), reference(&stiff));
    let stiff_sag = sag(&stiff_state);
    eprintln!(
        "reference sag: {limp_sag:.4} m without bending, {stiff_sag:.4} m with (dt {})",
        stiff.material.dt
    );
    // Without bending the strip folds down at its clamp and hangs: it sags by its free
    // length, 0.567 m. Bending springs hold it 5 cm higher.
    assert!(limp_sag > 0.45, "{limp_sag}");
    assert!(stiff_sag < limp_sag - 0.04, "{stiff_sag} vs {limp_sag}");
    for choice in float32_choices(context.is_some()) {
        let state = run(&stiff, choice, &context, seconds, None);
        let (error, sagged) = (
            relative_l2(&state.positions, &stiff_state.positions),
            sag(&state),
        );
        // A solver that left the bending springs out would sag by the limp strip's amount.
        assert!(
            (sagged - stiff_sag).abs() < 0.05 * (limp_sag - stiff_sag),
            "{}: sag {sagged} against the reference's {stiff_sag}",
            choice.name()
        );
        assert!(error < 1e-2, "{}: relative L2 error {error}", choice.name());
    }
}

/// A free square sheet, 0.5 m wide, in the x-z plane at rest, without gravity, damped by `c`
/// (kg/s), with the `[bending]` section `bending` (empty for none).
fn free_sheet(bending: &str, c: f64) -> Scene {
    build(&format!(
        r#"
[mesh]
generator = "grid"
resolution = [7, 7]
size = [0.5, 0.5]

[material]
mass = {{ total = 0.05 }}
stiffness = 400.0
damping = {c}

[simulation]
gravity = [0, 0, 0]

{bending}"#
    ))
}

/// Stiff bending springs for [`free_sheet`].
const BENDING: &str = "[bending]\nstiffness = 400.0\n";

/// The free sheet folded at right angles along its middle column: its half with x > 0 turned
/// up about the z axis, a rigid turn that stretches no edge spring.
fn folded(scene: &Scene) -> State {
    let positions = scene
        .model
        .initial_positions
        .iter()
        .map(|p| {
            if p.x > 1e-9 {
                DVec3::new(0.0, p.x, p.z)
            } else {
                *p
            }
        })
        .collect();
    State::at_rest(positions)
}

/// The angle between the sheet's halves, degrees: 90 folded at right angles, 180 flat.
/// `rest` gives each vertex's side: its x at rest.
fn opening(rest: &[DVec3], state: &State) -> f64 {
    let mean_of = |x: f64| {
        let column: Vec<DVec3> = (0..rest.len())
            .filter(|&v| (rest[v].x - x).abs() < 1e-9)
            .map(|v| state.positions[v])
            .collect();
        column.iter().sum::<DVec3>() / column.len() as f64
    };
    let hinge = mean_of(0.0);
    (mean_of(-0.25) - hinge)
        .angle_between(mean_of(0.25) - hinge)
        .to_degrees()
}

#[test]
fn a_folded_sheet_unfolds_with_bending_springs_and_stays_folded_without() {
    let context = test_context();
    let seconds = 0.4;
    let (limp, stiff) = (free_sheet("", 0.02), free_sheet(BENDING, 0.02));
    let (start, rest) = (folded(&stiff), &stiff.model.initial_positions);
    let reference = run(
        &stiff,
        SolverChoice::Reference,
        &context,
        seconds,
        Some(&start),
    );
    let opened = opening(rest, &reference);
    eprintln!(
        "reference: opened from 90 to {opened:.1} degrees in {seconds} s (dt {})",
        stiff.material.dt
    );
    assert!(opened > 160.0, "{opened}");
    for choice in std::iter::once(SolverChoice::Reference).chain(float32_choices(context.is_some()))
    {
        let kept = opening(rest, &run(&limp, choice, &context, seconds, Some(&start)));
        assert!(
            (kept - 90.0).abs() < 1.0,
            "{}: without bending {kept}",
            choice.name()
        );
        let state = run(&stiff, choice, &context, seconds, Some(&start));
        let error = relative_l2(&state.positions, &reference.positions);
        assert!(
            (opening(rest, &state) - opened).abs() < 1.0 && error < 2e-2,
            "{}: opened to {} (error {error})",
            choice.name(),
            opening(rest, &state)
        );
    }
}

/// Kinetic plus elastic energy, J (the free sheet has no gravity).
fn energy_of(scene: &Scene, state: &State) -> f64 {
    hooke_core::diagnostics::energy(&scene.model, state, &scene.material).total()
}

#[test]
fn bending_springs_own_damping_settles_a_folded_sheet_as_the_reference_does() {
    let context = test_context();
    let seconds = 0.3;
    // Undamped but for the bending springs' own dampers (0 N s/m: none at all).
    let sheet = |damping: f64| free_sheet(&format!("{BENDING}damping = {damping}\n"), 0.0);
    let (free, damped) = (sheet(0.0), sheet(0.01));
    assert_eq!(damped.model.bending_damping, 0.01);
    let start = folded(&damped);
    let energy_left =
        |scene: &Scene, state: &State| energy_of(scene, state) / energy_of(scene, &start);
    let undamped = run(
        &free,
        SolverChoice::Reference,
        &context,
        seconds,
        Some(&start),
    );
    let reference = run(
        &damped,
        SolverChoice::Reference,
        &context,
        seconds,
        Some(&start),
    );
    let (kept, left) = (
        energy_left(&free, &undamped),
        energy_left(&damped, &reference),
    );
    eprintln!("reference: {kept:.3} of the energy kept undamped, {left:.3} with dampers");
    // Verlet keeps an undamped sheet's energy (measured with the backward-difference velocity,
    // so within some 15%); the dampers take most of it.
    assert!(kept > 0.85, "{kept}");
    assert!(left < 0.3, "{left}");
    // Without any other damping the sheet rings, and 16-bit blending loses it within 0.3 s
    // whether or not it damps (37% off the reference undamped): held to its own bar elsewhere.
    let half = SolverChoice::Gpu(GpuMethod::Scatter(Accumulation::BlendR16f));
    for choice in float32_choices(context.is_some())
        .into_iter()
        .filter(|c| *c != half)
    {
        let state = run(&damped, choice, &context, seconds, Some(&start));
        let error = relative_l2(&state.positions, &reference.positions);
        let energy = energy_left(&damped, &state);
        // The sheet rings undamped but for the dampers: float atomics' order, different each
        // run, moves atomic-f32 up to 3% off; a missing damper puts it 30% off.
        assert!(
            error < 5e-2 && (energy - left).abs() < 0.02,
            "{}: error {error}, energy left {energy} (reference {left})",
            choice.name()
        );
    }
}

#[test]
fn a_running_simulation_takes_other_bending_stiffnesses_in_place() {
    let (stiff, limp) = (cantilever(Some(400.0)), cantilever(None));
    let cpu = SolverChoice::Cpu(CpuOptions::default());
    for (choice, bar) in [(SolverChoice::Reference, 1e-12), (cpu, 1e-5)] {
        let mut live = Simulation::from_scene(&stiff, choice, None).expect("solver");
        live.step(500).expect("stable");
        let snapshot = live.snapshot().expect("snapshot");
        live.set_model(stiff.model.with_bending_scale(0.0))
            .expect("same vertices");
        assert_eq!(live.steps_taken(), 500, "{}", choice.name());
        live.step(500).expect("stable");
        // The same as the strip without bending springs, continued from the same state.
        let mut rebuilt =
            Simulation::new(&limp.model, &stiff.material, choice, None).expect("solver");
        rebuilt.restore(&snapshot).expect("restore");
        rebuilt.step(500).expect("stable");
        let error = relative_l2(
            &live.state().expect("a").positions,
            &rebuilt.state().expect("b").positions,
        );
        assert!(error < bar, "{}: {error}", choice.name());
        // And not the same as keeping them.
        let mut kept = Simulation::from_scene(&stiff, choice, None).expect("solver");
        kept.restore(&snapshot).expect("restore");
        kept.step(500).expect("stable");
        let kept_error = relative_l2(
            &live.state().expect("a").positions,
            &kept.state().expect("c").positions,
        );
        assert!(kept_error > 100.0 * bar.max(1e-5), "{kept_error}");
    }
    let mut live = Simulation::from_scene(&stiff, cpu, None).expect("solver");
    let other = free_sheet(BENDING, 0.02).model;
    assert_eq!(
        live.set_model(other).unwrap_err().to_string(),
        "the new model has 49 vertices, the running one 30"
    );
}

#[test]
fn a_vertex_pinned_while_running_stays_where_it_was_put_until_unpinned() {
    let context = test_context();
    let strip = cantilever(None);
    // The free end's middle vertex, held up level with the clamp.
    let tip = (0..strip.model.vertex_count())
        .max_by(|a, b| {
            let (p, q) = (
                strip.model.initial_positions[*a],
                strip.model.initial_positions[*b],
            );
            (p.x - p.z.abs()).total_cmp(&(q.x - q.z.abs()))
        })
        .expect("vertices") as u32;
    let at = strip.model.initial_positions[tip as usize] + DVec3::new(-0.1, 0.05, 0.0);
    for choice in std::iter::once(SolverChoice::Reference).chain(float32_choices(context.is_some()))
    {
        let mut simulation =
            Simulation::from_scene(&strip, choice, context.clone()).expect("solver");
        simulation.step(300).expect("stable");
        simulation.pin(tip, Some(at)).expect("pin");
        simulation.step(2000).expect("stable");
        let state = simulation.state().expect("state");
        let held = state.positions[tip as usize];
        assert!(
            held.distance(at) < 1e-6,
            "{}: pinned at {at}, found at {held}",
            choice.name()
        );
        // Held up at both ends, the strip no longer hangs by its length.
        assert!(sag(&state) < 0.3, "{}: sag {}", choice.name(), sag(&state));
        simulation.unpin(tip).expect("unpin");
        simulation.step(300).expect("stable");
        let fallen = simulation.state().expect("state").positions[tip as usize];
        assert!(
            fallen.distance(at) > 0.02,
            "{}: {fallen} after unpinning",
            choice.name()
        );
    }
    let mut simulation = Simulation::from_scene(&strip, SolverChoice::Reference, None).expect("ok");
    assert_eq!(
        simulation.pin(30, None).unwrap_err().to_string(),
        "pinned vertex 30 does not exist (mesh has 30 vertices)"
    );
}

/// A 0.4 m curtain hanging from two handles at its top corners, which move 10 cm apart each
/// over half a second and then hold.
fn curtain_on_handles() -> Scene {
    let handle = |side: f64| {
        format!(
            "[[handle]]\nboxes = [{{ min = [{lo}, 1.19, -1], max = [{hi}, 1.21, 1] }}]\npath = [[0, 0, 0, 0], [0.5, {dx}, 0, 0]]\n",
            lo = side * 0.2 - 0.01,
            hi = side * 0.2 + 0.01,
            dx = side * 0.1,
        )
    };
    build(&format!(
        r#"
[mesh]
generator = "grid"
resolution = [9, 9]
size = [0.4, 0.4]
plane = "xy"
center = [0, 1, 0]

[material]
mass = {{ total = 0.05 }}
stiffness = 200.0
damping = 0.005

{}
{}"#,
        handle(-1.0),
        handle(1.0)
    ))
}

#[test]
fn a_curtain_hung_from_handles_moved_apart_is_stretched_as_the_reference_says() {
    let context = test_context();
    let scene = curtain_on_handles();
    let corners: Vec<u32> = scene.model.handles.iter().map(|h| h.vertices[0]).collect();
    assert_eq!(corners.len(), 2);
    let seconds = 1.0;
    let reference = run(&scene, SolverChoice::Reference, &context, seconds, None);
    let stretch = |state: &State| {
        let springs = &scene.model;
        (0..springs.spring_count())
            .map(|s| {
                let [a, b] = springs.spring_ends[s];
                let l = state.positions[a as usize].distance(state.positions[b as usize]);
                l / springs.rest_lengths[s] - 1.0
            })
            .fold(0.0, f64::max)
    };
    let expected = stretch(&reference);
    eprintln!("reference: largest strain {expected:.4} with the handles 0.6 m apart");
    // The handles pull the top edge from 0.4 to 0.6 m: its springs stretch.
    assert!(expected > 0.1, "{expected}");
    for choice in std::iter::once(SolverChoice::Reference).chain(float32_choices(context.is_some()))
    {
        let state = run(&scene, choice, &context, seconds, None);
        for (&v, dx) in corners.iter().zip([-0.1, 0.1]) {
            let start = scene.model.initial_positions[v as usize];
            let held = state.positions[v as usize];
            assert!(
                held.distance(start + DVec3::new(dx, 0.0, 0.0)) < 1e-6,
                "{}: handle vertex {v} at {held}, from {start}",
                choice.name()
            );
        }
        let error = relative_l2(&state.positions, &reference.positions);
        // Handles left where they started would leave the strain near zero.
        assert!(
            (stretch(&state) - expected).abs() < 0.02 * expected && error < 1e-3,
            "{}: strain {} (error {error})",
            choice.name(),
            stretch(&state)
        );
    }
}

#[test]
fn a_vertex_attached_to_a_ball_stays_on_it() {
    let context = test_context();
    // A sheet whose middle vertex is attached to a dynamic ball just below it; the ball falls
    // to the ground and rolls to rest, carrying the sheet's middle with it.
    let scene = build(
        r#"
[mesh]
generator = "grid"
resolution = [9, 9]
size = [0.4, 0.4]
center = [0, 1.62, 0]

[material]
mass = { total = 0.02 }
stiffness = 100.0
damping = 0.002

[[collider]]
kind = "sphere"
center = [0, 1.5, 0]
radius = 0.1
mass = 0.5
velocity = [0.3, 0, 0]

[[collider]]
kind = "plane"
point = [0, 0, 0]
normal = [0, 1, 0]

[[handle]]
boxes = [{ min = [-0.01, 1.6, -0.01], max = [0.01, 1.7, 0.01] }]
collider = 0
"#,
    );
    let middle = scene.model.handles[0].vertices[0];
    let offset = scene.model.initial_positions[middle as usize] - DVec3::new(0.0, 1.5, 0.0);
    for choice in std::iter::once(SolverChoice::Reference).chain(float32_choices(context.is_some()))
    {
        let mut simulation =
            Simulation::from_scene(&scene, choice, context.clone()).expect("solver");
        for _ in 0..4 {
            simulation.step(500).expect("stable");
            let center = match simulation.colliders().expect("colliders")[0].shape {
                hooke_core::collide::Shape::Sphere { center, .. } => center,
                _ => unreachable!("a sphere"),
            };
            let on = simulation.state().expect("state").positions[middle as usize] - center;
            assert!(
                (on - offset).length() < 1e-5,
                "{} at t = {:.2} s: the vertex is at {on} from the ball, attached at {offset}",
                choice.name(),
                simulation.time()
            );
            assert!(center.y < 1.5 || simulation.time() < 0.1);
        }
    }
}

#[test]
fn the_viewer_pins_a_grabbed_vertex_and_scales_bending_while_running() {
    use hooke::live::{Choice, LiveSimulation};
    use hooke::live_view::LiveView;
    let Some(context) = test_context() else {
        return;
    };
    let scene = cantilever(Some(400.0));
    let first_bending = scene.model.spring_count() - scene.model.bending_springs;
    for choice in [Choice::Cpu(Method::Gather), Choice::Gpu(GpuMethod::Gather)] {
        let mut live = LiveSimulation::new(Arc::clone(&context), scene.clone(), choice)
            .expect("live simulation");
        let format = wgpu::TextureFormat::Rgba8Unorm;
        let mut view = LiveView::new(&context, &live, format, [64, 48]).expect("view");
        let target = context.device.create_texture(&wgpu::TextureDescriptor {
            label: Some("test target"),
            size: wgpu::Extent3d {
                width: 64,
                height: 48,
                depth_or_array_layers: 1,
            },
            mip_level_count: 1,
            sample_count: 1,
            dimension: wgpu::TextureDimension::D2,
            format,
            usage: wgpu::TextureUsages::RENDER_ATTACHMENT,
            view_formats: &[],
        });
        let target = target.create_view(&Default::default());
        let frame = |live: &mut LiveSimulation, view: &mut LiveView| {
            let mut encoder = context.device.create_command_encoder(&Default::default());
            live.encode_frame(&mut encoder);
            view.encode(&context, &mut encoder, live, &target)
                .expect("frame");
            context.queue.submit([encoder.finish()]);
            live.after_submit();
        };
        frame(&mut live, &mut view);
        // What P does while the tip is held 5 cm above where it started.
        let tip = 29;
        let held = scene.model.initial_positions[tip as usize].as_vec3() + glam::Vec3::Y * 0.05;
        live.pin_grabbed(Some((tip, held)));
        assert!(live.model().pinned[tip as usize] && live.added_pins() == 1);
        assert_eq!(live.pins_changed(), 1);
        let bending_off_and_pin_kept = |live: &LiveSimulation| {
            let bending = &live.model().stiffnesses[first_bending..];
            assert!(bending.iter().all(|k| *k == 0.0) && live.added_pins() == 1);
        };
        // The bending slider to 0 rebuilds the solver with the pins as they are.
        live.bending_scale = 0.0;
        live.apply();
        bending_off_and_pin_kept(&live);
        frame(&mut live, &mut view);
        // The bending damping slider: the same rebuild, the pins and bending scale kept.
        live.bending_damping = 0.01;
        live.apply();
        assert_eq!(live.model().bending_damping, 0.01);
        bending_off_and_pin_kept(&live);
        frame(&mut live, &mut view);
        live.unpin_added();
        assert_eq!((live.added_pins(), live.pins_changed()), (0, 2));
        frame(&mut live, &mut view);
        context.take_error().expect("no GPU validation error");
        assert!(live.steps_taken() > 0, "{}", choice.label());
    }
}
