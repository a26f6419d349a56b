//! Test fixtures shared by the test suites of several crates (a dev-dependency only): small
//! scenes, kept as files in `scenes/`, and checks that every solver must pass, written once.
#![allow(clippy::unwrap_used, clippy::missing_panics_doc)] // test code: a failure is a panic

use std::path::{Path, PathBuf};

use hooke_core::reference::ReferenceSolver;
use hooke_core::scene::{MeshSection, Scene, SceneFile};
use hooke_core::{Solver, State};

/// The folder of the scenes hooke ships (`scenes/` at the workspace root).
pub fn shipped_scenes_dir() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("../../scenes")
}

/// The shipped scene file `scenes/NAME`.
pub fn shipped_scene_path(name: &str) -> PathBuf {
    shipped_scenes_dir().join(name)
}

/// The shipped scene `scenes/NAME`, built as `hooke run` builds it.
pub fn shipped_scene(name: &str) -> Scene {
    let path = shipped_scene_path(name);
    SceneFile::load(&path)
        .and_then(|file| file.build(&path, false))
        .unwrap_or_else(|e| panic!("{e}"))
}

/// The scene in the TOML `text`, built as `hooke run` builds a file named `name`.
pub fn scene_from_text(text: &str, name: &str) -> Scene {
    SceneFile::parse(text, name)
        .and_then(|file| file.build(Path::new(name), false))
        .unwrap_or_else(|e| panic!("{e}"))
}

/// The benchmark workload on `mesh` (of `vertices` vertices), built as `hooke bench` builds
/// it: its dt exceeds the (conservative) stability bound on irregular meshes, where valences
/// reach 12.
pub fn benchmark_scene(mesh: MeshSection, vertices: u32) -> Scene {
    SceneFile::benchmark(mesh, vertices)
        .build(Path::new("bench"), true)
        .unwrap_or_else(|e| panic!("{e}"))
}

/// The float64 reference solver of `scene`, driven by the scene's control.
pub fn reference(scene: &Scene) -> ReferenceSolver {
    let mut solver = ReferenceSolver::new(&scene.model, &scene.material);
    solver.set_control(&scene.control).expect("control");
    solver
}

/// The solver's state (a read-back on the GPU).
pub fn state_of(solver: &dyn Solver) -> State {
    solver.read_state().expect("state reads back")
}

/// A deliberately broken solver: what an accuracy bar must tell apart from a working one.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Broken {
    /// Returns the initial state whatever it is asked.
    NeverMoves,
    /// Every spring's stiffness is 0: points fall and blow in the wind, unconnected.
    SpringsOff,
    /// Every spring 1% too stiff.
    StiffnessOnePercentOff,
    /// The damping term of eq. 2 left out.
    DampingIgnored,
}

impl Broken {
    pub const ALL: [Self; 4] = [
        Self::NeverMoves,
        Self::SpringsOff,
        Self::StiffnessOnePercentOff,
        Self::DampingIgnored,
    ];

    pub fn name(self) -> &'static str {
        match self {
            Self::NeverMoves => "never moves",
            Self::SpringsOff => "springs off",
            Self::StiffnessOnePercentOff => "stiffness 1% off",
            Self::DampingIgnored => "damping ignored",
        }
    }

    /// The relative L2 error of this broken solver against `expected`, the reference's positions
    /// after `steps` steps of `scene`. The broken variants run on the float64 reference, so the
    /// score is the bug's alone.
    pub fn score(self, scene: &Scene, steps: u32, expected: &[glam::DVec3]) -> f64 {
        let mut broken = scene.clone();
        match self {
            Self::NeverMoves => {
                return hooke_core::diagnostics::relative_l2(
                    &scene.model.initial_positions,
                    expected,
                );
            }
            Self::SpringsOff => broken.model.stiffnesses.iter_mut().for_each(|k| *k = 0.0),
            Self::StiffnessOnePercentOff => broken.material.stiffness_scale *= 1.01,
            Self::DampingIgnored => broken.material.damping = 0.0,
        }
        let mut solver = reference(&broken);
        solver.step(steps).expect("stable");
        hooke_core::diagnostics::relative_l2(&state_of(&solver).positions, expected)
    }

    /// Every broken solver's score on `scene` (see [`Broken::score`]), printed.
    pub fn scores(scene: &Scene, steps: u32, expected: &[glam::DVec3]) -> Vec<(Self, f64)> {
        let scores: Vec<(Self, f64)> = Self::ALL
            .iter()
            .map(|b| (*b, b.score(scene, steps, expected)))
            .collect();
        let printed: Vec<String> = scores
            .iter()
            .map(|(b, s)| format!("{}: {s:.1e}", b.name()))
            .collect();
        eprintln!("broken solvers score: {}", printed.join(", "));
        scores
    }
}

/// Requires an accuracy `bar` (a relative L2 error a working solver stays below) to reject
/// every broken solver in `scores`: a bar that a broken solver passes proves nothing.
pub fn assert_bar_rejects_broken(bar: f64, scores: &[(Broken, f64)], what: &str) {
    for (broken, score) in scores {
        assert!(
            bar < *score,
            "{what}: the bar {bar:e} passes a solver whose {} ({score:e})",
            broken.name()
        );
    }
}

/// The folder of the fixture scenes.
pub fn scenes_dir() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("scenes")
}

/// Builds fixture scene `name` and runs it at half the stable time step (test scenes compare
/// solvers, so they stay well inside the bound).
fn build(name: &str) -> Scene {
    let path = scenes_dir().join(format!("{name}.toml"));
    let mut scene = SceneFile::load(&path)
        .and_then(|file| file.build(&path, false))
        .unwrap_or_else(|e| panic!("test scene {name}: {e}"));
    scene.material.dt = 0.5 * scene.max_stable_dt;
    scene
}

/// A free 20 x 20 cloth, 1 m wide, dropped from 1 m onto a ball of radius 0.3 m resting on the
/// ground plane; thickness 1 cm, some friction. Built at 0.5 of the stable dt.
pub fn cloth_onto_ball() -> Scene {
    build("cloth-onto-ball")
}

/// A 16 x 16 curtain hanging from its top edge, and a ball of radius 0.15 m moving through it
/// along +z at 0.5 m/s (a kinematic collider); thickness 5 mm. Built at 0.5 of the stable dt.
pub fn curtain_and_moving_ball() -> Scene {
    build("curtain-and-moving-ball")
}

/// The paper's Fig. 3 in small: an upright 24 x 24 cloth, 0.6 m wide, lands on its lower edge,
/// tips over in a light wind and folds onto itself on the ground. Self-collision keeps
/// unjoined vertices 13 mm apart (about half the spacing), K = 4 grids of 26 mm cells.
/// Built at 0.5 of the stable dt.
pub fn folding_cloth() -> Scene {
    build("folding-cloth")
}

/// The scene file of [`folding_cloth`], for tests that go through the command line.
pub const FOLDING_CLOTH: &str = include_str!("../scenes/folding-cloth.toml");

/// Unjoined vertex pairs closer than half the self-collision distance: layers of cloth that
/// passed into each other.
pub fn interpenetrating_pairs(scene: &Scene, state: &hooke_core::State) -> usize {
    let config = scene
        .model
        .collision
        .self_collision
        .expect("a scene with self-collision");
    let positions: Vec<glam::Vec3> = state.positions.iter().map(|p| p.as_vec3()).collect();
    hooke_core::selfcollide::exact_pairs(&positions, &scene.model.adjacency, 0.5 * config.distance)
        .len()
}

/// A 16 x 16 sheet, 1 m wide, pinned at its corners, and a dynamic ball (0.2 kg, radius
/// 0.15 m) dropped onto its middle from 0.3 m above; thickness 5 mm. Built at 0.5 of the
/// stable dt.
pub fn ball_onto_sheet() -> Scene {
    build("ball-onto-sheet")
}

/// Drops the ball of `ball_onto_sheet` and checks the exchange of momentum: it falls freely
/// until it meets the sheet, is then slowed by it (the sheet takes its momentum), comes to
/// rest on it, and its weight ends up on the pins.
pub fn check_ball_dropped_on_sheet(solver: &mut dyn Solver, scene: &Scene) {
    use hooke_core::collide::Shape;
    let dt = scene.material.dt;
    let g = scene.material.gravity.y;
    let ball = |solver: &dyn Solver| {
        let collider = solver.colliders().unwrap()[0];
        let Shape::Sphere { center, .. } = collider.shape else {
            panic!("a sphere")
        };
        (center, collider.velocity)
    };
    let (start, _) = ball(solver);
    let mut slowed = false;
    let mut lowest = f64::INFINITY;
    for _ in 0..120 {
        solver.step(50).expect("stable");
        let t = solver.steps_taken() as f64 * dt;
        let (center, velocity) = ball(solver);
        let free_fall = g * t;
        if center.y > start.y + 0.5 * g * t * t - 0.2 - 1e-9 && t < 0.2 {
            // Before contact (the sheet is 0.3 m below the ball's bottom): free fall.
            assert!(
                (velocity.y - free_fall).abs() < 1e-3 * free_fall.abs() + 1e-6,
                "{} t = {t}: {} vs {free_fall}",
                solver.describe(),
                velocity.y
            );
        }
        slowed |= velocity.y > 0.5 * free_fall && t > 0.3;
        let cloth_low = state_of(solver)
            .positions
            .iter()
            .map(|p| p.y)
            .fold(f64::INFINITY, f64::min);
        // The ball never falls through: its bottom stays above the sheet's lowest point.
        assert!(
            center.y - 0.15 > cloth_low - 0.02,
            "{}: ball bottom {} below the sheet {cloth_low}",
            solver.describe(),
            center.y - 0.15
        );
        lowest = lowest.min(center.y);
    }
    assert!(
        slowed,
        "{}: the sheet did not slow the ball",
        solver.describe()
    );
    let (center, velocity) = ball(solver);
    assert!(
        velocity.length() < 0.05,
        "{}: the ball is still moving at {velocity}",
        solver.describe()
    );
    // It rests in the sheet's sag, below where it met the sheet, above its lowest bounce.
    assert!(
        center.y < 1.15 && center.y >= lowest,
        "{}: {center}",
        solver.describe()
    );
    // At rest the ball's weight has gone through the sheet to the pins (time-averaged).
    let total = mean_pin_reaction(solver, scene, 500);
    let weight = (scene.model.total_mass() + 0.2) * scene.material.gravity;
    assert!(
        (total + weight).length() < 0.02 * weight.length(),
        "{}: pins hold {total}, cloth and ball weigh {weight}",
        solver.describe()
    );
}

/// The sum of the pins' reactions averaged over the next `steps` steps, as a force sensor
/// would measure it: a float32 cloth's rounding limit cycle makes the instantaneous sum wobble
/// by the momentum it exchanges, which averages out.
pub fn mean_pin_reaction(solver: &mut dyn Solver, scene: &Scene, steps: u32) -> glam::DVec3 {
    let mut total = glam::DVec3::ZERO;
    for _ in 0..steps {
        solver.step(1).expect("stable");
        let positions = state_of(solver).positions;
        total += hooke_core::diagnostics::pin_reactions(&scene.model, &positions, &scene.material)
            .iter()
            .map(|(_, r)| *r)
            .sum::<glam::DVec3>();
    }
    total / f64::from(steps)
}

/// [`ball_onto_sheet`] with a ball so light and pushed so hard that it leaves the numbers in
/// its first step: every solver must say so, naming the step and the collider.
pub fn exploding_ball() -> Scene {
    let mut scene = ball_onto_sheet();
    let dynamics = scene.model.collision.colliders[0]
        .dynamics
        .as_mut()
        .expect("a dynamic ball");
    dynamics.mass = 1e-300;
    dynamics.force = glam::DVec3::new(1e308, 0.0, 0.0);
    scene
}

/// [`cloth_onto_ball`] with the ball replaced by a capsule lying along z, its axis from
/// z = -0.6 to 0.6 at 0.3 m height, radius 0.1 m: the cloth folds over a bar.
pub fn cloth_onto_capsule() -> Scene {
    let mut scene = cloth_onto_ball();
    scene.model.collision.colliders[0].shape = hooke_core::collide::Shape::Capsule {
        start: glam::DVec3::new(0.0, 0.3, -0.6),
        end: glam::DVec3::new(0.0, 0.3, 0.6),
        radius: 0.1,
    };
    scene
}

/// Steps a scene with round colliders (spheres, capsules) and planes for 4000 steps and checks
/// the cloth never comes closer than the thickness less `tolerance` to any of them, and
/// reaches a round one. Projection puts a vertex exactly at the thickness: `tolerance` covers
/// float32 rounding (1e-6 m on the CPU; GPU sqrt and division may be 2.5 ulp off, 1e-5 m).
pub fn check_cloth_stays_out(solver: &mut dyn Solver, scene: &Scene, tolerance: f64) {
    use hooke_core::collide::Shape;
    let thickness = scene.model.collision.thickness;
    let mut touched = false;
    for _ in 0..40 {
        solver.step(100).expect("stable");
        for p in state_of(solver).positions {
            for collider in &scene.model.collision.colliders {
                let clearance = collider.shape.clearance(p);
                assert!(
                    clearance > thickness - tolerance,
                    "{}: {clearance} from {:?} at {p} after {} steps",
                    solver.describe(),
                    collider.shape,
                    solver.steps_taken()
                );
                if !matches!(collider.shape, Shape::Plane { .. }) {
                    touched |= clearance < thickness + 1e-3;
                }
            }
        }
    }
    assert!(
        touched,
        "{}: the cloth never reached the ball or bar",
        solver.describe()
    );
}

/// Steps [`curtain_and_moving_ball`] for 3000 steps and checks the cloth stays out of the
/// kinematic ball where its script puts it (within `tolerance`, as in
/// [`check_cloth_stays_out`]) and that the ball, travelling from z = -0.3 past the curtain at
/// z = 0, drags cloth more than 0.1 m along.
pub fn check_curtain_pushed(solver: &mut dyn Solver, scene: &Scene, tolerance: f64) {
    let ball = scene.model.collision.colliders[0];
    let thickness = scene.model.collision.thickness;
    let mut pushed: f64 = 0.0;
    for _ in 0..30 {
        solver.step(100).expect("stable");
        let t = solver.steps_taken() as f64 * scene.material.dt;
        let ball_now = ball.at(t).shape;
        for p in state_of(solver).positions {
            let clearance = ball_now.clearance(p);
            assert!(
                clearance > thickness - tolerance,
                "{} at t = {t}: {clearance}",
                solver.describe()
            );
            pushed = pushed.max(p.z);
        }
    }
    assert!(
        pushed > 0.1,
        "{}: the curtain moved only {pushed} m",
        solver.describe()
    );
}
