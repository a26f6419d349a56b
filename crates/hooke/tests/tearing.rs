//! Tearing on every solver: a sheet pulled apart by handles on two edges tears along a line
//! between them, the same springs break on the reference and the CPU solver, nothing breaks
//! below the threshold, torn springs survive a snapshot and a state file, and the renderer stops
//! drawing torn triangles.

use std::sync::Arc;

use hooke::state_file::{load_state, save_state};
use hooke::{OffscreenRun, Simulation, SolverChoice};
use hooke_core::diagnostics::max_strain;
use hooke_core::scene::Scene;
use hooke_core::{Model, State};
use hooke_cpu::{CpuOptions, Method};
use hooke_gpu::{Accumulation, GpuContext, GpuMethod, test_context};
use hooke_testkit::scene_from_text;

fn cpu(method: Method) -> SolverChoice {
    SolverChoice::Cpu(CpuOptions {
        method,
        ..Default::default()
    })
}

/// A 16 x 7 strip (0.64 m by 0.24 m) with damped bending springs (a torn one damps no more),
/// held by handles on its left and
/// right columns that draw apart by `pull` m each over 0.5 s, with a softer band down the
/// middle column of cells, weightless (so the pull alone tears it); springs break past
/// `max_stretch` (none when `None`).
fn strip(pull: f64, max_stretch: Option<f64>) -> Scene {
    let tearing = max_stretch.map_or(String::new(), |s| format!("[tearing]\nmax_stretch = {s}\n"));
    let text = format!(
        r#"
[mesh]
generator = "grid"
resolution = [16, 7]
size = [0.64, 0.24]
plane = "xy"
center = [0.0, 1.0, 0.0]

[material]
mass = {{ total = 0.02 }}
stiffness = 200.0
damping = 0.002

[[material.stiffness_region]]
min = [-0.03, 0.0, -1.0]
max = [0.03, 2.0, 1.0]
factor = 0.35

[bending]
stiffness = 10.0
damping = 0.005

[simulation]
dt = "auto"
steps = 1
gravity = [0.0, 0.0, 0.0]

[[handle]]
boxes = [{{ min = [-0.33, 0.0, -1], max = [-0.31, 2.0, 1] }}]
path = [[0, 0, 0, 0], [0.5, -{pull}, 0, 0]]

[[handle]]
boxes = [{{ min = [0.31, 0.0, -1], max = [0.33, 2.0, 1] }}]
path = [[0, 0, 0, 0], [0.5, {pull}, 0, 0]]

{tearing}"#
    );
    scene_from_text(&text, "strip.toml")
}

/// Simulated time: the pull and a little after.
const SECONDS: f64 = 0.6;

fn steps(scene: &Scene) -> u32 {
    (SECONDS / scene.material.dt).round() as u32
}

fn run(scene: &Scene, choice: SolverChoice, context: &Option<Arc<GpuContext>>) -> Simulation {
    let mut simulation = Simulation::from_scene(scene, choice, context.clone()).expect("solver");
    simulation.step(steps(scene)).expect("stable");
    simulation
}

/// Groups of vertices joined by whole edge springs (bending springs aside).
fn pieces(model: &Model, broken: &[u32]) -> Vec<usize> {
    let mut parent: Vec<usize> = (0..model.vertex_count()).collect();
    fn root(parent: &mut [usize], mut v: usize) -> usize {
        while parent[v] != v {
            parent[v] = parent[parent[v]];
            v = parent[v];
        }
        v
    }
    for (s, [a, b]) in model.spring_ends.iter().enumerate() {
        if model.is_bending(s) || broken.contains(&(s as u32)) {
            continue;
        }
        let (ra, rb) = (
            root(&mut parent, *a as usize),
            root(&mut parent, *b as usize),
        );
        parent[ra] = rb;
    }
    (0..model.vertex_count())
        .map(|v| root(&mut parent, v))
        .collect()
}

/// Checks that `broken` splits the strip in two, each half holding one handle, along the soft
/// middle band (every broken edge has both ends within a cell and a half of x = 0), and that
/// the halves came apart in `state`: their nearest vertices are more than `gap` m apart.
fn assert_torn_along_the_middle(
    model: &Model,
    state: &State,
    broken: &[u32],
    gap: f64,
    solver: &str,
) {
    let piece = pieces(model, broken);
    let mut distinct = piece.clone();
    distinct.sort_unstable();
    distinct.dedup();
    assert_eq!(distinct.len(), 2, "{solver}: {} pieces", distinct.len());
    let [left, right] =
        [&model.handles[0], &model.handles[1]].map(|h| piece[h.vertices[0] as usize]);
    assert_ne!(left, right, "{solver}: the handles are still joined");
    for h in 0..2 {
        let expected = [left, right][h];
        assert!(
            model.handles[h]
                .vertices
                .iter()
                .all(|&v| piece[v as usize] == expected),
            "{solver}: handle {h} is split"
        );
    }
    let mut nearest = f64::INFINITY;
    for (a, p) in state.positions.iter().enumerate() {
        for (b, q) in state.positions.iter().enumerate() {
            if piece[a] == left && piece[b] == right {
                nearest = nearest.min(p.distance(*q));
            }
        }
    }
    eprintln!(
        "{solver}: {} broken, the halves {nearest:.4} m apart",
        broken.len()
    );
    assert!(
        nearest > gap,
        "{solver}: the halves are only {nearest:.4} m apart"
    );
    for &s in broken {
        if model.is_bending(s as usize) {
            continue;
        }
        for v in model.spring_ends[s as usize] {
            let x = model.initial_positions[v as usize].x;
            assert!(
                x.abs() < 0.065,
                "{solver}: spring {s} broke at x = {x:.3}, outside the band"
            );
        }
    }
}

/// How far apart the halves must end. Torn, each shrinks back toward its rest width and the
/// gap grows to about the 0.2 m the handles moved plus the band; a spring still pulling across
/// the cut (stretched at most 1.3 times its 4.3 cm) would hold it under 6 cm.
const GAP: f64 = 0.15;

#[test]
fn a_strip_pulled_by_two_edges_tears_along_a_line_between_them_on_every_solver() {
    let scene = strip(0.1, Some(1.3));
    let reference = run(&scene, SolverChoice::Reference, &None);
    let expected = reference.broken_springs().expect("broken springs");
    let reference_state = reference.state().expect("state");
    assert_torn_along_the_middle(&scene.model, &reference_state, &expected, GAP, "reference");
    // The same springs break on the CPU solver, with either data structure.
    for method in Method::ALL {
        let simulation = run(&scene, cpu(method), &None);
        let broken = simulation.broken_springs().expect("broken springs");
        assert_eq!(broken, expected, "cpu {}", method.name());
        let state = simulation.state().expect("state");
        let name = format!("cpu {}", method.name());
        assert_torn_along_the_middle(&scene.model, &state, &broken, GAP, &name);
        // And it ends where the reference does (a torn spring pulls and damps no more).
        let farthest = state
            .positions
            .iter()
            .zip(&reference_state.positions)
            .map(|(p, q)| p.distance(*q))
            .fold(0.0, f64::max);
        eprintln!("{name}: {farthest:.2e} m from the reference at most");
        assert!(farthest < 1e-4, "{name}: {farthest} m from the reference");
    }
    // Every GPU method tears it the same way (sums in other orders: the very same springs are
    // not promised, the line is). Blend-rgba8's 8-bit forces are not enough to pull it apart.
    let context = test_context();
    if context.is_some() {
        for method in GpuMethod::all() {
            if method == GpuMethod::Scatter(Accumulation::BlendRgba8) {
                continue;
            }
            let Ok(mut simulation) =
                Simulation::from_scene(&scene, SolverChoice::Gpu(method), context.clone())
            else {
                continue; // an accumulation this adapter lacks
            };
            simulation.step(steps(&scene)).expect("stable");
            let broken = simulation.broken_springs().expect("read back");
            let state = simulation.state().expect("state");
            let name = format!("gpu {}", method.name());
            assert_torn_along_the_middle(&scene.model, &state, &broken, GAP, &name);
            let (n, m) = (broken.len() as f64, expected.len() as f64);
            assert!(
                (n - m).abs() <= 0.2 * m,
                "{}: {n} broken, reference {m}",
                method.name()
            );
        }
    }
}

/// The largest stretch (length over rest length) any spring reaches in the run, sampled at
/// every step on the CPU.
fn largest_stretch(scene: &Scene) -> f64 {
    let mut simulation = Simulation::from_scene(scene, cpu(Method::Gather), None).expect("solver");
    let mut largest = 0.0f64;
    for _ in 0..steps(scene) {
        let state = simulation.state().expect("state");
        largest = largest.max(1.0 + max_strain(&scene.model, &state.positions).0);
        simulation.step(1).expect("stable");
    }
    largest
}

#[test]
fn nothing_tears_below_the_threshold_and_something_does_just_above_it() {
    // Pulled by 1 cm a side: no spring is stretched more than a few percent.
    let gentle = strip(0.01, None);
    let largest = largest_stretch(&gentle);
    assert!(largest > 1.02 && largest < 1.3, "largest stretch {largest}");
    let whole = run(&gentle, cpu(Method::Gather), &None)
        .state()
        .expect("state");
    let context = test_context();
    let mut choices = vec![
        SolverChoice::Reference,
        cpu(Method::Gather),
        cpu(Method::Scatter),
    ];
    if context.is_some() {
        choices.extend([
            SolverChoice::Gpu(GpuMethod::Gather),
            SolverChoice::Gpu(GpuMethod::Scatter(Accumulation::Incidence)),
        ]);
    }
    for choice in choices {
        // A threshold 2% above the largest stretch breaks nothing...
        let above = strip(0.01, Some(largest * 1.02));
        let simulation = run(&above, choice, &context);
        assert_eq!(
            simulation.broken_springs().expect("read"),
            [],
            "{}",
            choice.name()
        );
        if choice == cpu(Method::Gather) {
            // ... and changes nothing: the CPU steps the very same bits as without tearing.
            assert_eq!(simulation.state().expect("state"), whole);
        }
        // ... and one 2% below it breaks some springs.
        let below = strip(0.01, Some(largest * 0.98));
        let simulation = run(&below, choice, &context);
        assert!(
            !simulation.broken_springs().expect("read").is_empty(),
            "{}: nothing broke at {:.4}",
            choice.name(),
            largest * 0.98
        );
    }
}

#[test]
fn torn_springs_are_kept_by_snapshots_and_state_files_and_stay_torn_on_another_solver() {
    let scene = strip(0.1, Some(1.3));
    let total = steps(&scene);
    let mut straight = Simulation::from_scene(&scene, cpu(Method::Gather), None).expect("solver");
    straight.step(total).expect("stable");
    // Stop where the tear has begun but not finished.
    let mut first = Simulation::from_scene(&scene, cpu(Method::Gather), None).expect("solver");
    let mut taken = 0;
    while first.broken_springs().expect("read").is_empty() {
        first.step(1).expect("stable");
        taken += 1;
    }
    let snapshot = first.snapshot().expect("snapshot");
    let final_count = straight.broken_springs().expect("read").len();
    assert!(
        !snapshot.broken_springs.is_empty() && snapshot.broken_springs.len() < final_count,
        "{} of {final_count} broken at the snapshot",
        snapshot.broken_springs.len()
    );
    // Through a state file and back.
    let directory = std::env::temp_dir().join(format!("hooke-tearing-{}", std::process::id()));
    std::fs::create_dir_all(&directory).expect("directory");
    let path = directory.join("torn.ply");
    save_state(&path, &snapshot, &scene.model, scene.material.dt).expect("save");
    let loaded = load_state(&path, &scene.model, scene.material.dt).expect("load");
    std::fs::remove_dir_all(&directory).expect("clean up");
    assert_eq!(loaded.broken_springs, snapshot.broken_springs);
    // Continued from the file, the CPU ends exactly where the uninterrupted run did.
    let mut resumed = Simulation::from_scene(&scene, cpu(Method::Gather), None).expect("solver");
    resumed.restore(&loaded).expect("restore");
    resumed.step(total - taken).expect("stable");
    assert_eq!(
        resumed.state().expect("state"),
        straight.state().expect("state")
    );
    assert_eq!(
        resumed.broken_springs().expect("read"),
        straight.broken_springs().expect("read")
    );
    // Every other solver takes the tears over: they stay broken and exert no force, even on a
    // model that does not tear, which keeps them without adding any.
    let context = test_context();
    let mut others = vec![SolverChoice::Reference, cpu(Method::Scatter)];
    if context.is_some() {
        others.extend([
            SolverChoice::Gpu(GpuMethod::Gather),
            SolverChoice::Gpu(GpuMethod::Scatter(Accumulation::Incidence)),
        ]);
    }
    let untearing = strip(0.1, None);
    for choice in others {
        for scene in [&scene, &untearing] {
            let mut other = Simulation::from_scene(scene, choice, context.clone()).expect("solver");
            other.restore(&snapshot).expect("restore");
            assert_eq!(
                other.broken_springs().expect("read"),
                snapshot.broken_springs
            );
            other.step(50).expect("stable");
            let broken = other.broken_springs().expect("read");
            assert!(snapshot.broken_springs.iter().all(|s| broken.contains(s)));
            if scene.model.tearing.is_none() {
                assert_eq!(broken, snapshot.broken_springs, "{}", choice.name());
            }
            // The torn springs pull on nothing: the halves drift apart by more than the
            // springs' limit allows.
            let state: State = other.state().expect("state");
            let torn = other.torn_model().expect("model");
            let (strain, _) = max_strain(&torn, &state.positions);
            assert!(strain < 1.0, "{}: strain {strain}", choice.name());
        }
    }
}

#[test]
fn triangles_with_a_broken_edge_are_not_drawn() {
    let Some(context) = test_context() else {
        return;
    };
    let scene = strip(0.1, Some(1.3));
    let untearing = strip(0.1, None);
    // Reddish pixels: the cloth's checker squares (the sky is blue, the ground grey).
    let cloth_pixels = |image: &hooke_gpu::render::Image| {
        image
            .rgba
            .chunks(4)
            .filter(|p| i32::from(p[0]) > i32::from(p[2]) + 60)
            .count()
    };
    for choice in [
        cpu(Method::Gather),
        SolverChoice::Gpu(GpuMethod::Scatter(Accumulation::Incidence)),
    ] {
        let mut simulation =
            Simulation::from_scene(&scene, choice, Some(Arc::clone(&context))).expect("solver");
        simulation.step(steps(&scene)).expect("stable");
        let state = simulation.state().expect("state");
        let mut torn = OffscreenRun::new(simulation, [320, 240]).expect("renderer");
        let torn_image = torn.frame(0).expect("frame");
        // The same positions drawn by a renderer that knows of no tears: the stretched
        // triangles across the cut are drawn.
        let mut whole =
            Simulation::from_scene(&untearing, choice, Some(Arc::clone(&context))).expect("solver");
        whole.set_state(&state);
        let mut whole = OffscreenRun::new(whole, [320, 240]).expect("renderer");
        let whole_image = whole.frame(0).expect("frame");
        let (torn_count, whole_count) = (cloth_pixels(&torn_image), cloth_pixels(&whole_image));
        assert!(
            torn_count > 1000 && torn_count + 200 < whole_count,
            "{}: {torn_count} cloth pixels torn, {whole_count} drawn whole",
            choice.name()
        );
    }
    context.take_error().expect("no GPU validation error");
}

#[test]
fn the_viewer_counts_torn_springs_without_waiting_and_takes_another_threshold_running() {
    use hooke::live::{Choice, LiveSimulation};
    use hooke::live_view::LiveView;
    use hooke_gpu::render::OffscreenTarget;
    let Some(context) = test_context() else {
        return;
    };
    let scene = strip(0.1, Some(1.3));
    let expected = run(&scene, SolverChoice::Reference, &None)
        .broken_springs()
        .expect("read")
        .len();
    let target = OffscreenTarget::new(&context, [64, 48]);
    let frame = |live: &mut LiveSimulation, view: &mut LiveView| {
        let mut encoder = context.device.create_command_encoder(&Default::default());
        live.encode_frame(&mut encoder);
        view.encode(&context, &mut encoder, live, &target.view)
            .expect("frame");
        context.queue.submit([encoder.finish()]);
        live.after_submit();
    };
    for choice in [
        Choice::Cpu(Method::Gather),
        Choice::Gpu(GpuMethod::Scatter(Accumulation::Incidence)),
    ] {
        let mut live = LiveSimulation::new(Arc::clone(&context), scene.clone(), choice)
            .expect("live simulation");
        let mut view =
            LiveView::new(&context, &live, OffscreenTarget::FORMAT, target.size).expect("view");
        live.steps_per_frame = 20;
        let reads = context.blocking_reads();
        let mut frames = 0;
        // Frames until the panel's count reaches the reference's (the GPU's arrives a few
        // frames after the steps that broke the springs).
        while live.broken_springs() < expected && frames < 400 {
            frame(&mut live, &mut view);
            frames += 1;
        }
        assert_eq!(live.broken_springs(), expected, "{}", choice.label());
        assert_eq!(
            context.blocking_reads(),
            reads,
            "{}: a frame waited",
            choice.label()
        );
        // Another threshold: the solver is rebuilt with it and the torn springs stay torn.
        live.max_stretch = 2.0;
        live.apply();
        let tearing = live.model().tearing.expect("tears");
        assert_eq!(tearing.max_stretch, 2.0);
        assert!(live.message.is_none(), "{:?}", live.message);
        // The rebuilt solver counts the torn springs it took over (on the GPU, at its next
        // status read-backs).
        for _ in 0..10 {
            frame(&mut live, &mut view);
        }
        assert_eq!(live.broken_springs(), expected, "{}", choice.label());
    }
    context.take_error().expect("no GPU validation error");
}

/// A sheet of springs of one stiffness, pinned at its corners, that cannot tear: the GPU's
/// gather then reads less than each spring's entry. `mesh` is the mesh section's generator
/// lines: a grid's springs become a stencil; an irregular mesh's keep their entries, the
/// stiffness taken from the uniforms.
fn uniform_sheet(mesh: &str) -> Scene {
    let text = r#"
[mesh]
MESH
size = [0.5, 0.5]
plane = "xz"
center = [0.0, 1.0, 0.0]

[material]
mass = { total = 0.05 }
stiffness = 100.0
damping = 0.001

[pins]
select = ["corners"]

[simulation]
dt = "auto"
steps = 1
gravity = [0.0, -9.81, 0.0]
"#;
    scene_from_text(&text.replace("MESH", mesh), "sheet.toml")
}

#[test]
fn a_gpu_gather_of_one_stiffness_takes_a_restored_snapshots_tears() {
    let context = test_context();
    if context.is_none() {
        return;
    }
    for (mesh, variant) in [
        ("generator = \"grid\"\nresolution = [12, 12]", "stencil"),
        (
            "generator = \"irregular\"\nvertices = 144\nseed = 3",
            "one stiffness",
        ),
    ] {
        let scene = uniform_sheet(mesh);
        let gpu = Simulation::from_scene(
            &scene,
            SolverChoice::Gpu(GpuMethod::Gather),
            context.clone(),
        )
        .expect("solver");
        assert!(gpu.describe().contains(variant), "{}", gpu.describe());
        check_restored_tears(&scene, &context, GpuMethod::Gather);
    }
}

#[test]
fn gpu_atomic_scatter_over_a_stencil_takes_a_restored_snapshots_tears() {
    let Some(gpu) = test_context() else { return };
    let scene = uniform_sheet("generator = \"grid\"\nresolution = [12, 12]");
    let mut accumulations = vec![Accumulation::AtomicFixed];
    if gpu.has(hooke_gpu::wgpu::Features::SHADER_FLOAT32_ATOMIC) {
        accumulations.push(Accumulation::AtomicF32);
    }
    let context = Some(gpu);
    for accumulation in accumulations {
        let method = GpuMethod::Scatter(accumulation);
        let solver = Simulation::from_scene(&scene, SolverChoice::Gpu(method), context.clone())
            .expect("solver");
        // A grid's springs that cannot tear: the kernel runs over the stencil, not the records.
        assert!(
            solver.describe().contains("stencil"),
            "{}",
            solver.describe()
        );
        check_restored_tears(&scene, &context, method);
    }
}

/// A snapshot of `scene` with the springs across its middle cut, restored on the CPU and on
/// the GPU with `method` (whose solver could not tear): the halves part alike.
fn check_restored_tears(scene: &Scene, context: &Option<Arc<GpuContext>>, method: GpuMethod) {
    let mut cpu_run = Simulation::from_scene(scene, cpu(Method::Gather), None).expect("solver");
    cpu_run.step(100).expect("stable");
    let mut snapshot = cpu_run.snapshot().expect("snapshot");
    // Cut every spring that crosses the sheet's middle (x = 0).
    let positions = &scene.model.initial_positions;
    snapshot.broken_springs = (0..scene.model.spring_count() as u32)
        .filter(|&s| {
            let [a, b] = scene.model.spring_ends[s as usize];
            (positions[a as usize].x < 0.0) != (positions[b as usize].x < 0.0)
        })
        .collect();
    assert!(snapshot.broken_springs.len() > 12);
    let after = |choice: SolverChoice| {
        let mut simulation =
            Simulation::from_scene(scene, choice, context.clone()).expect("solver");
        simulation.restore(&snapshot).expect("restore");
        simulation.step(200).expect("stable");
        simulation.state().expect("state").positions
    };
    let on_cpu = after(cpu(Method::Gather));
    let on_gpu = after(SolverChoice::Gpu(method));
    let largest = |a: &[glam::DVec3], b: &[glam::DVec3]| {
        a.iter()
            .zip(b)
            .map(|(p, q)| p.distance(*q))
            .fold(0.0, f64::max)
    };
    // The cut halves sag apart; springs still pulling would hold them together.
    cpu_run.step(200).expect("stable");
    let uncut = cpu_run.state().expect("state").positions;
    assert!(
        largest(&on_cpu, &uncut) > 0.01,
        "{}",
        largest(&on_cpu, &uncut)
    );
    assert!(
        largest(&on_gpu, &on_cpu) < 1e-5,
        "{}",
        largest(&on_gpu, &on_cpu)
    );
}
