//! `hooke run`: simulate a scene and write frames (binary PLY, an OBJ sequence or a Blender
//! point cache).

use std::path::{Path, PathBuf};
use std::time::{Duration, Instant};

use anyhow::Context;
use clap::Args;
use hooke::Simulation;
use hooke::state_file::{load_state, save_state};
use hooke_core::State;
use hooke_core::collide::Shape;
use hooke_core::diagnostics::{Energy, check_health, energy, max_strain};
use hooke_core::frames::{FrameDestination, FrameFormat, FrameTiming, FrameWriter};
use hooke_core::scene::Scene;
use indicatif::{ProgressBar, ProgressStyle};
use serde::Serialize;

use crate::scene_loading::load_scene;
use crate::solvers::SolverArgs;

#[derive(Debug, Args)]
pub struct RunArgs {
    /// Scene file (TOML).
    pub scene: PathBuf,
    #[command(flatten)]
    pub solver: SolverArgs,
    /// Number of steps (default: the scene's simulation.steps).
    #[arg(long)]
    pub steps: Option<u64>,
    /// Directory for frames and the final state (default: out/<scene name>); or, ending in
    /// `.usda` or `.pc2`, the one file the frames go to, with the final state and summary
    /// beside it (`cloth.usda`: `cloth.final-state.ply`, `cloth.summary.json`).
    #[arg(long)]
    pub output: Option<PathBuf>,
    /// Steps between written frames (default: the scene's simulation.frame_every).
    #[arg(long)]
    pub frame_every: Option<u64>,
    /// Write only the final state, no frames.
    #[arg(long)]
    pub no_frames: bool,
    /// Frame files: `ply` (frame-NNNNNNN.ply, binary), `obj` (frame-NNNNNNN.obj with UVs and
    /// normals, an OBJ sequence), `pc2` (frames.pc2, Blender's point cache for the Mesh Cache
    /// modifier) or `usda` (frames.usda, a USD stage with UVs and the colliders); the last two
    /// are renamed into place when the run ends. Vertex order is always the mesh file's.
    /// Default: the `--output` file's extension, else `ply`.
    #[arg(long, value_parser = parse_frame_format)]
    pub output_format: Option<FrameFormat>,
    /// Run even if dt exceeds the stability bound.
    #[arg(long)]
    pub allow_unstable: bool,
    /// Continue from a state a run saved (its `final-state.ply`, with `final-state.toml`
    /// beside it): positions, velocities, the step counter and the dynamic balls; then run
    /// `--steps` more steps.
    #[arg(long)]
    pub resume: Option<PathBuf>,
}

/// Steps between checks for an exploding simulation (non-finite values are caught every step).
const HEALTH_CHECK_INTERVAL: u64 = 100;

#[derive(Debug, Serialize)]
struct Summary {
    scene: String,
    solver: String,
    vertices: usize,
    springs: usize,
    /// Steps run by this invocation.
    steps: u64,
    /// The step the run started from (0, or the resumed state's).
    first_step: u64,
    dt: f64,
    simulated_seconds: f64,
    solver_seconds: f64,
    steps_per_second: f64,
    ms_per_step: f64,
    energy_kinetic: f64,
    energy_elastic: f64,
    energy_gravitational: f64,
    energy_total: f64,
    /// Of the springs that still hold.
    max_strain: f64,
    /// Springs torn (see `[tearing]`), in all: a resumed run counts those it started with.
    broken_springs: usize,
    frames_written: usize,
    output: PathBuf,
    /// The state to `--resume` from (its `.toml` beside it).
    final_state: PathBuf,
    /// Where the dynamic balls ended.
    balls: Vec<BallSummary>,
}

#[derive(Debug, Serialize)]
struct BallSummary {
    /// Index of the `[[collider]]` entry.
    collider: usize,
    center: [f64; 3],
    velocity: [f64; 3],
}

/// Where a run's files go: a directory of frames, `final-state.ply` and `summary.json`, or one
/// frames file (`cloth.usda`) with `cloth.final-state.ply` and `cloth.summary.json` beside it.
struct OutputPlan {
    frames: FrameDestination,
    /// Put before the state's and summary's names: `cloth.` beside `cloth.usda`.
    prefix: String,
}

impl OutputPlan {
    fn new(args: &RunArgs, scene_name: &str) -> anyhow::Result<Self> {
        let output = args
            .output
            .clone()
            .unwrap_or_else(|| Path::new("out").join(scene_name));
        let frames = FrameDestination::resolve(&output, args.output_format).map_err(|c| {
            anyhow::anyhow!(
                "--output {} is a .{} file but --output-format is {}",
                output.display(),
                c.named.name(),
                c.given.name()
            )
        })?;
        let prefix = match &frames.file {
            Some(file) => format!(
                "{}.",
                file.file_stem().unwrap_or_default().to_string_lossy()
            ),
            None => String::new(),
        };
        Ok(Self { frames, prefix })
    }

    fn file(&self, name: &str) -> PathBuf {
        self.frames.directory.join(format!("{}{name}", self.prefix))
    }

    /// What the summary calls the output: the directory, or the frames file.
    fn shown(&self) -> &Path {
        self.frames
            .file
            .as_deref()
            .unwrap_or(&self.frames.directory)
    }
}

pub fn run(args: &RunArgs) -> anyhow::Result<()> {
    let scene = load_scene(&args.scene, args.allow_unstable)?;
    let steps = args.steps.unwrap_or(scene.steps);
    let frame_every = args.frame_every.unwrap_or(scene.frame_every).max(1);
    let plan = OutputPlan::new(args, &scene.name)?;
    let output = plan.frames.directory.clone();
    std::fs::create_dir_all(&output)
        .with_context(|| format!("creating output directory {}", output.display()))?;

    let mut solver = args.solver.build(&scene)?;
    if let Some(path) = &args.resume {
        let snapshot = load_state(path, &scene.model, scene.material.dt)
            .with_context(|| format!("resuming from {}", path.display()))?;
        solver.restore(&snapshot)?;
        eprintln!("resumed from step {}", snapshot.steps_taken);
    }
    let first_step = solver.steps_taken();
    eprintln!(
        "{}: {} vertices, {} springs, dt {:.3e} s (stable up to {:.3e} s), {} steps on {}",
        scene.name,
        scene.model.vertex_count(),
        scene.model.spring_count(),
        scene.material.dt,
        scene.max_stable_dt,
        steps,
        solver.describe()
    );

    let progress = progress_bar(steps);
    let timing = FrameTiming {
        dt: scene.material.dt,
        frame_every,
    };
    let mut frames = FrameWriter::to(
        &plan.frames,
        &scene.name,
        &scene.model.triangles,
        scene.mesh.uvs.as_ref(),
        timing,
    );
    if !args.no_frames {
        write_frame(&mut frames, &solver, &solver.state()?, first_step)?;
    }

    let mut solver_time = Duration::ZERO;
    let mut step = 0u64;
    while step < steps {
        let until_frame = frame_every - step % frame_every;
        let until_check = HEALTH_CHECK_INTERVAL - step % HEALTH_CHECK_INTERVAL;
        let batch = (steps - step).min(until_frame).min(until_check);
        let start = Instant::now();
        let result = solver.step(batch as u32);
        solver_time += start.elapsed();
        step += batch;
        progress.set_position(step);
        let state = match result.and_then(|()| {
            let state = solver.state()?;
            check_health(
                &*solver.torn_model()?,
                &state.positions,
                solver.steps_taken(),
            )?;
            Ok(state)
        }) {
            Ok(state) => state,
            Err(error) => return Err(stopped(error, plan.shown(), frames)),
        };
        if !args.no_frames && (step.is_multiple_of(frame_every) || step == steps) {
            write_frame(&mut frames, &solver, &state, first_step + step)?;
        }
    }
    let frames_written = frames
        .finish()
        .with_context(|| format!("finishing the frames in {}", output.display()))?;
    progress.finish_and_clear();

    let snapshot = solver.snapshot()?;
    let state = snapshot.state.clone();
    let final_path = plan.file("final-state.ply");
    save_state(&final_path, &snapshot, &scene.model, scene.material.dt)
        .with_context(|| format!("writing {}", final_path.display()))?;
    let summary = summarize(
        &scene,
        &solver,
        &state,
        steps,
        solver_time,
        frames_written,
        &plan,
    )?;
    print_summary(
        &summary,
        &energy(&*solver.torn_model()?, &state, &scene.material),
    );
    let json = serde_json::to_string_pretty(&summary)?;
    let summary_path = plan.file("summary.json");
    hooke_core::atomic_file::write_atomically(&summary_path, |file| {
        std::io::Write::write_all(file, json.as_bytes())
    })
    .with_context(|| format!("writing {}", summary_path.display()))?;
    Ok(())
}

/// Writes one frame: the state's positions and, for formats that draw them, the colliders.
fn write_frame(
    frames: &mut FrameWriter,
    solver: &Simulation,
    state: &State,
    step: u64,
) -> anyhow::Result<()> {
    let colliders = if frames.draws_colliders() {
        solver.colliders()?
    } else {
        Vec::new()
    };
    frames
        .write(step, &state.positions, &colliders)
        .with_context(|| format!("writing {}", frames.path(step).display()))
}

/// The error of a simulation that stopped, after completing the frames written before it (a
/// `.pc2` file keeps them).
fn stopped(error: hooke_core::SimError, output: &Path, frames: FrameWriter) -> anyhow::Error {
    let kept = match frames.finish() {
        Ok(count) => format!("frames written before: {count}"),
        Err(e) => format!("the frames could not be completed: {e}"),
    };
    anyhow::anyhow!(
        "{error}\nthe simulation stopped; {kept}, in {}",
        output.display()
    )
}

fn parse_frame_format(name: &str) -> Result<FrameFormat, String> {
    FrameFormat::from_name(name)
        .ok_or_else(|| format!("expected one of {}", FrameFormat::choices()))
}

fn progress_bar(steps: u64) -> ProgressBar {
    let bar = ProgressBar::new(steps);
    bar.set_style(
        ProgressStyle::with_template("{bar:40} {pos}/{len} steps  {per_sec}  eta {eta}")
            .unwrap_or_else(|_| ProgressStyle::default_bar()),
    );
    bar
}

fn summarize(
    scene: &Scene,
    solver: &Simulation,
    state: &State,
    steps: u64,
    solver_time: Duration,
    frames_written: usize,
    plan: &OutputPlan,
) -> anyhow::Result<Summary> {
    let colliders = solver.colliders()?;
    let model = solver.torn_model()?;
    let e = energy(&model, state, &scene.material);
    let broken_springs = solver.broken_springs()?.len();
    let seconds = solver_time.as_secs_f64();
    Ok(Summary {
        scene: scene.name.clone(),
        solver: solver.describe(),
        vertices: scene.model.vertex_count(),
        springs: scene.model.spring_count(),
        steps,
        first_step: solver.steps_taken() - steps,
        dt: scene.material.dt,
        simulated_seconds: steps as f64 * scene.material.dt,
        solver_seconds: seconds,
        steps_per_second: if seconds > 0.0 {
            steps as f64 / seconds
        } else {
            0.0
        },
        ms_per_step: if steps > 0 {
            1e3 * seconds / steps as f64
        } else {
            0.0
        },
        energy_kinetic: e.kinetic,
        energy_elastic: e.elastic,
        energy_gravitational: e.gravitational,
        energy_total: e.total(),
        max_strain: max_strain(&model, &state.positions).0,
        broken_springs,
        frames_written,
        output: plan.shown().to_path_buf(),
        final_state: plan.file("final-state.ply"),
        balls: colliders
            .iter()
            .enumerate()
            .filter(|(_, c)| c.dynamics.is_some())
            .filter_map(|(k, c)| match c.shape {
                Shape::Sphere { center, .. } => Some(BallSummary {
                    collider: k,
                    center: center.to_array(),
                    velocity: c.velocity.to_array(),
                }),
                Shape::Plane { .. } | Shape::Capsule { .. } => None,
            })
            .collect(),
    })
}

fn print_summary(s: &Summary, e: &Energy) {
    println!("scene        {}", s.scene);
    println!("solver       {}", s.solver);
    println!(
        "steps        {} x {:.3e} s = {:.4} s simulated",
        s.steps, s.dt, s.simulated_seconds
    );
    println!(
        "speed        {:.0} steps/s ({:.3} ms/step, solver only)",
        s.steps_per_second, s.ms_per_step
    );
    println!(
        "energy       {:.6e} J (kinetic {:.3e}, elastic {:.3e}, gravitational {:.3e})",
        e.total(),
        e.kinetic,
        e.elastic,
        e.gravitational
    );
    println!("max strain   {:.4}%", 100.0 * s.max_strain);
    if s.broken_springs > 0 {
        println!("torn         {} springs broken", s.broken_springs);
    }
    for ball in &s.balls {
        let [x, y, z] = ball.center;
        let speed = glam::DVec3::from_array(ball.velocity).length();
        println!(
            "ball         collider {} at ({x:.3}, {y:.3}, {z:.3}) m, {speed:.3} m/s",
            ball.collider
        );
    }
    println!(
        "output       {} ({} frames); state {} and .toml; summary.json",
        s.output.display(),
        s.frames_written,
        s.final_state.display()
    );
}
