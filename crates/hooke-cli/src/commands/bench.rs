//! `hooke bench`: the paper's Table 2 on this machine.
//!
//! Workload (fixed for comparability with other engines): a unit square in the x-z plane with
//! its 4 corners pinned, m = 1/N per vertex, dt = 1e-3 s, D = 0.25 m/dt^2, c = 0.01 m/dt,
//! gravity -9.81 m/s^2 along y. Each method first runs warm-up steps, then `--steps` fused steps
//! a round timed in batches of 10 (the real step, "total"), then `--steps` phase-separated
//! steps whose phases are timed one by one (per-phase columns; the fused step keeps each
//! vertex's forces in registers and makes one pass instead of two or three). On the GPU the
//! phase-timed steps also go 10 to a submission, each pass between timestamps: timed one
//! submission at a time, an H200's passes read over twice as long in one call as in another
//! while the fused steps' times stayed the same. All times are medians per step.
//!
//! Every solver is built and warmed up first, and then the fused steps are timed in `--rounds`
//! rounds (5 unless told), each round timing every solver in turn: a machine whose speed
//! drifts (a shared VM's can move by 2x over seconds) slows every row of a round alike, so
//! rows compare fairly, and the spread over rounds says how far one figure can be trusted.
//! "total" is then the median of the rounds' medians, shown with their range.
//!
//! Paired ratios set rows against each other round by round, per spring: the irregular mesh and
//! the shuffled grid against the grid with the same vertex count, each larger grid against the
//! smallest, and a row with self-collision against the same mesh without it (which `hooke
//! bench --self-collision K` times as well). A ratio of two medians taken in different rounds
//! moves with the machine's speed; a ratio within a round does not, or much less.
//!
//! Each solver's state is checked, untimed, after the rounds and after the phase-timed steps,
//! as `hooke run` checks it: where it has exploded, the row says so and from when. A plain
//! spring step costs the same on any state, but a self-collision step's cost follows the
//! contact, and a figure of a state no run would keep should say it is one.
//!
//! The bandwidth floor is the bytes one fused step must move at least once divided by the copy
//! bandwidth measured on the spot, with the same threads, on a buffer as large as those bytes:
//! it is the time a perfect memory-bound step would take at the cache level where the data lives.

use std::path::Path;
use std::time::{Duration, Instant};

use anyhow::Context;
use clap::{Args, ValueEnum};
use comfy_table::Table;
use hooke::{EngineError, MemoryReport, Simulation, SolverChoice};
use hooke_core::diagnostics::check_health;
use hooke_core::scene::{MeshSection, Scene, SceneFile};
use hooke_core::selfcollide::{self, PartTimes, SelfCollision};
use hooke_core::{PhaseTimes, SimError, TimingSource};
use hooke_cpu::kernels::InstructionSet;
use hooke_cpu::{CpuOptions, Method};
use hooke_gpu::{Accumulation, GpuError, GpuMethod, TIMED_STEPS_PER_SUBMISSION};
use rayon::prelude::*;
use serde::Serialize;

use crate::format::{OutputFormat, bytes, table};
use crate::solvers::{MethodArg, OrderArg, open_gpu};

/// Which solvers `hooke bench` times.
#[derive(Clone, Copy, Debug, PartialEq, Eq, ValueEnum)]
pub enum BenchBackend {
    Cpu,
    Gpu,
    /// CPU and GPU side by side.
    All,
}

#[derive(Debug, Args)]
pub struct BenchArgs {
    /// Solvers to time: the cpu methods, the gpu methods (every accumulation), or both.
    #[arg(long, value_enum, default_value_t = BenchBackend::Cpu)]
    pub backend: BenchBackend,
    /// Regular grids to run, as vertices per side.
    #[arg(long, value_delimiter = ',', default_values_t = [128u32, 256, 512, 1024])]
    pub sizes: Vec<u32>,
    /// Vertices of the irregular mesh (0 to skip it).
    #[arg(long, default_value_t = 65_536)]
    pub irregular: u32,
    /// Side of a grid whose vertices are numbered in a random order, as meshes exported
    /// without care for locality are (0 to skip it); compare with the same grid in order.
    #[arg(long, default_value_t = 256)]
    pub shuffled: u32,
    /// CPU methods to run.
    #[arg(long, value_enum, value_delimiter = ',', default_values_t = [MethodArg::Gather, MethodArg::Scatter])]
    pub methods: Vec<MethodArg>,
    /// GPU methods to run (default: every one): gather, or a scatter accumulation by its name
    /// (atomic-f32, atomic-fixed, incidence, blend-r32f, blend-r16f, blend-rgba8).
    #[arg(long, value_delimiter = ',', value_parser = parse_gpu_method)]
    pub gpu_methods: Option<Vec<GpuMethod>>,
    /// Worker threads (default: one per core).
    #[arg(long)]
    pub threads: Option<usize>,
    /// Vertex order.
    #[arg(long, value_enum, default_value_t = OrderArg::Auto)]
    pub order: OrderArg,
    /// Timed steps per method and round (fused), and then once more phase-separated.
    #[arg(long, default_value_t = 100)]
    pub steps: u32,
    /// Add self-collision (Section 5) with this many staggered grids to every workload; its
    /// cost shows as the collision phase. Distance: half the shortest spring; cells twice that.
    /// Each workload also runs without it, in the same rounds, for the paired ratio.
    #[arg(long, value_name = "K")]
    pub self_collision: Option<u32>,
    /// Add bending springs (one across every interior edge) with this fraction of the edge
    /// springs' stiffness to every workload: they about double the valences, and this shows
    /// what that costs each method.
    #[arg(long, value_name = "FRACTION")]
    pub bending: Option<f64>,
    /// Untimed steps before timing.
    #[arg(long, default_value_t = 50)]
    pub warmup: u32,
    /// Rounds of fused-step timing, every solver in turn each round: total is the median of
    /// the rounds, and the table shows their range.
    // Five by default, of 100 steps (one of 300 before, at the same cost in steps): one
    // round's figures carry no range, and on this project's VM they moved with its spells
    // unseen (the irregular gather's paired ratio read 0.90-1.42 over eight runs of one
    // round; five rounds showed rounds from 0.52 to 3.52 beside medians of 0.76-1.37).
    #[arg(long, default_value_t = 5, value_parser = clap::value_parser!(u32).range(1..))]
    pub rounds: u32,
    #[arg(long, value_enum, default_value_t = OutputFormat::Table)]
    pub format: OutputFormat,
}

/// A GPU method by the name `hooke bench` prints (`gather`, `scatter/incidence`) or by its
/// accumulation's alone (`incidence`).
fn parse_gpu_method(name: &str) -> Result<GpuMethod, String> {
    GpuMethod::from_name(name)
        .or_else(|| Accumulation::from_name(name).map(GpuMethod::Scatter))
        .ok_or_else(|| {
            let names: Vec<String> = GpuMethod::all().into_iter().map(GpuMethod::name).collect();
            format!("no GPU method {name:?}; one of {}", names.join(", "))
        })
}

#[derive(Debug, Serialize)]
struct Row {
    mesh: String,
    #[serde(skip)]
    kind: MeshKind,
    /// Self-collision's staggered grids, if the workload has it.
    self_collision: Option<u32>,
    vertices: usize,
    springs: usize,
    backend: &'static str,
    method: String,
    /// CPU threads, or 0 for the GPU.
    threads: usize,
    /// Where the phase times come from: "wall clock" (cpu, or gpu without timestamps) or "gpu
    /// timestamps, 10 steps a submission".
    phase_timing: String,
    force_calculation_ms: f64,
    force_accumulation_ms: Option<f64>,
    /// None where one pass sums the springs and integrates (the GPU's gather): its force
    /// calculation includes the integration.
    integration_ms: Option<f64>,
    /// Collider and self-collision passes, when the workload has them.
    collision_ms: Option<f64>,
    /// The self-collision's parts, where the solver times them (the CPU's).
    self_collision_parts_ms: Option<SelfCollisionParts>,
    phased_total_ms: f64,
    /// Median of the rounds' medians of the fused step.
    total_ms: f64,
    /// Each round's median of the fused step, in the order run.
    total_rounds_ms: Vec<f64>,
    /// When the row's state was first found exploded (`hooke run`'s check, made after the
    /// rounds and after the phase-timed steps), and how; its times before the check may be, in
    /// part or in full, of that state.
    exploded: Option<String>,
    springs_per_second: f64,
    bytes_per_step: usize,
    /// GPU: the compute dispatches and draws one step records.
    dispatches_per_step: Option<u32>,
    copy_bandwidth_gb_per_s: Option<f64>,
    bandwidth_floor_ms: Option<f64>,
    dt_above_stability_bound: bool,
    /// CPU: the steps its fused step advanced per sweep over memory (1: one at a time).
    steps_per_sweep: Option<usize>,
}

#[derive(Debug, Serialize)]
struct Report {
    cpu: String,
    simd: &'static str,
    threads: usize,
    gpu: Option<String>,
    steps: u32,
    rounds: u32,
    rows: Vec<Row>,
    paired: Vec<Paired>,
    /// Methods whose accumulation could not hold this workload's forces (fixed point, which
    /// clamps and reports): "mesh method: why". The others still ran.
    skipped: Vec<String>,
}

pub fn run(args: &BenchArgs) -> anyhow::Result<()> {
    let threads = args.threads.unwrap_or_else(rayon::current_num_threads);
    let copy_pool = rayon::ThreadPoolBuilder::new()
        .num_threads(threads)
        .build()?;
    let mut meshes: Vec<MeshKind> = args.sizes.iter().map(|&n| MeshKind::Grid(n)).collect();
    if args.irregular > 0 {
        meshes.push(MeshKind::Irregular(args.irregular));
    }
    if args.shuffled > 0 {
        meshes.push(MeshKind::Shuffled(args.shuffled));
    }
    // With self-collision, each workload also runs without it (first), for the paired ratio.
    let variants: Vec<Option<u32>> = match args.self_collision {
        Some(grids) => vec![None, Some(grids)],
        None => vec![None],
    };
    let gpu = match args.backend {
        BenchBackend::Cpu => None,
        BenchBackend::Gpu | BenchBackend::All => Some(open_gpu()?),
    };
    let run_cpu = args.backend != BenchBackend::Gpu;
    let mut scenes = Vec::new();
    let mut timed: Vec<Timed> = Vec::new();
    let mut skipped = Vec::new();
    let workloads = meshes
        .into_iter()
        .flat_map(|kind| variants.iter().map(move |&grids| (kind, grids)));
    for (kind, self_collision) in workloads {
        let name = kind.name();
        let scene = workload_scene(&name, kind, args, self_collision)?;
        let name = match args.bending {
            Some(_) => format!("{name} + bending"),
            None => name,
        };
        let name = match self_collision {
            Some(grids) => format!("{name} + self-collision {grids}"),
            None => name,
        };
        let gpu_methods = args.gpu_methods.clone().unwrap_or_else(GpuMethod::all);
        let gpu_choices = gpu
            .iter()
            .flat_map(|_| gpu_methods.iter().copied().map(SolverChoice::Gpu));
        let cpu_choices = args.methods.iter().filter(|_| run_cpu).map(|method| {
            SolverChoice::Cpu(CpuOptions {
                method: (*method).into(),
                threads: Some(threads),
                order: args.order.into(),
                ..Default::default()
            })
        });
        for choice in gpu_choices.chain(cpu_choices) {
            let mut simulation = match Simulation::from_scene(&scene, choice, gpu.clone()) {
                Ok(simulation) => simulation,
                Err(EngineError::Gpu(GpuError::Unsupported { .. })) => continue,
                Err(error) => {
                    return Err(error).with_context(|| format!("{name}, {}", choice.name()));
                }
            };
            let warmed = simulation.step(args.warmup).map_err(anyhow::Error::from);
            let entry = Timed {
                name: name.clone(),
                kind,
                self_collision,
                scene: scenes.len(),
                simulation,
                rounds_ms: Vec::new(),
                exploded: None,
            };
            if entry.keep(warmed, &mut skipped)?.is_some() {
                timed.push(entry);
            }
        }
        scenes.push(scene);
    }
    for _ in 0..args.rounds {
        let mut kept = Vec::with_capacity(timed.len());
        for mut entry in timed {
            let timing = median_step_ms(&mut entry.simulation, args);
            if let Some(ms) = entry.keep(timing, &mut skipped)? {
                entry.rounds_ms.push(ms);
                kept.push(entry);
            }
        }
        timed = kept;
    }
    // Checked after the rounds, not between them: a check reads the whole state in float64
    // (200 MB at 2048^2), and with one after every row of every round the 512^2 gather row,
    // timed right after the 2048^2 rows' checks, took 1.05 ms against 0.55 (a median of 11
    // rounds of the large-mesh command); a check after the warm-ups put 1.04 ms in its range.
    for entry in &mut timed {
        entry.note_explosion("by the end of the rounds")?;
    }
    let mut rows = Vec::new();
    let mut finished = Vec::new();
    for mut entry in timed {
        let scene = &scenes[entry.scene];
        let measured = measure(&mut entry, scene, args, &copy_pool);
        if let Some(row) = entry.keep(measured, &mut skipped)? {
            if args.format == OutputFormat::Table {
                eprintln!(
                    "  {} {} {}: {:.3} ms/step",
                    row.mesh, row.backend, row.method, row.total_ms
                );
            }
            rows.push(row);
            finished.push(entry);
        }
    }
    for (row, mut entry) in rows.iter_mut().zip(finished) {
        entry.note_explosion("after the phase-timed steps")?;
        row.exploded = entry.exploded;
    }
    let report = Report {
        cpu: cpu_name(),
        simd: InstructionSet::Best.resolved_name(),
        threads,
        gpu: gpu.as_ref().map(|c| c.describe()),
        steps: args.steps,
        rounds: args.rounds,
        paired: paired(&rows),
        rows,
        skipped,
    };
    match args.format {
        OutputFormat::Json => println!("{}", serde_json::to_string_pretty(&report)?),
        OutputFormat::Table => print_report(&report),
    }
    Ok(())
}

/// The benchmark scene of `workload`, with the bending springs asked for and self-collision
/// with `self_collision` grids.
fn workload_scene(
    name: &str,
    workload: MeshKind,
    args: &BenchArgs,
    self_collision: Option<u32>,
) -> anyhow::Result<Scene> {
    let mut scene = benchmark_scene(workload).with_context(|| format!("building {name}"))?;
    if let Some(fraction) = args.bending {
        let stiffness = fraction * scene.model.stiffnesses[0];
        let pairs = scene.mesh.bending_pairs();
        scene
            .model
            .add_bending_springs(&pairs, stiffness, 1.0)
            .map_err(|e| anyhow::anyhow!("--bending {fraction}: {e}"))?;
    }
    if let Some(grids) = self_collision {
        anyhow::ensure!(
            (1..=selfcollide::MAX_GRIDS).contains(&grids),
            "--self-collision: {grids} grids is outside 1..={}",
            selfcollide::MAX_GRIDS
        );
        scene.model.collision.self_collision = Some(SelfCollision {
            grids,
            ..SelfCollision::for_model(&scene.model)
        });
    }
    Ok(scene)
}

/// A solver being timed: its workload, and its fused step's median in each round so far.
struct Timed {
    name: String,
    kind: MeshKind,
    self_collision: Option<u32>,
    /// Index of its scene.
    scene: usize,
    simulation: Simulation,
    rounds_ms: Vec<f64>,
    /// When its state was first found exploded, and how (see [`explosion`]).
    exploded: Option<String>,
}

impl Timed {
    /// Checks the state (untimed) until it is first found exploded, and notes when.
    fn note_explosion(&mut self, when: &str) -> anyhow::Result<()> {
        if self.exploded.is_none() {
            let found = explosion(&self.simulation)
                .with_context(|| format!("{}, {}", self.name, self.simulation.describe()))?;
            self.exploded = found.map(|why| format!("{when} ({why})"));
        }
        Ok(())
    }

    /// `result`'s value; `None`, noted in `skipped`, if the method's accumulation could not
    /// hold this workload's forces (the others still run); any other failure ends the bench.
    fn keep<T>(
        &self,
        result: anyhow::Result<T>,
        skipped: &mut Vec<String>,
    ) -> anyhow::Result<Option<T>> {
        match result {
            Ok(value) => Ok(Some(value)),
            Err(error) if out_of_range(&error) => {
                let why = format!(
                    "{} {}: {error:#}",
                    self.name,
                    self.simulation.choice().name()
                );
                eprintln!("  skipped {why}");
                skipped.push(why);
                Ok(None)
            }
            Err(error) => {
                Err(error.context(format!("{}, {}", self.name, self.simulation.describe())))
            }
        }
    }
}

/// True when a method failed because its accumulation's range could not hold the workload's
/// forces (a property of the method, not a fault of the run).
fn out_of_range(error: &anyhow::Error) -> bool {
    error.chain().any(|cause| {
        matches!(
            cause.downcast_ref::<EngineError>(),
            Some(EngineError::Simulation(SimError::Overflow { .. }))
        ) || matches!(
            cause.downcast_ref::<SimError>(),
            Some(SimError::Overflow { .. })
        )
    })
}

/// `hooke run`'s check of a state (no spring stretched past `EXPLOSION_STRETCH` rest lengths,
/// every position finite): `Ok(Some(why))` where the state has exploded, which the bench notes
/// and times on; an error where a position is not finite or the state cannot be read. The
/// workload's springs are soft for its mass (the corner pins carry the whole cloth), so a
/// long run stretches the corners without end: past 100 rest lengths by step 1,600 at 512^2
/// and by step 400 at 2048^2.
fn explosion(simulation: &Simulation) -> Result<Option<String>, SimError> {
    let state = simulation.state()?;
    let model = simulation.torn_model()?;
    match check_health(&model, &state.positions, simulation.steps_taken()) {
        Ok(()) => Ok(None),
        Err(exploded @ SimError::Exploded { .. }) => Ok(Some(exploded.to_string())),
        Err(error) => Err(error),
    }
}

/// Seed of the benchmark's irregular mesh (`scenes/bench-irregular.toml` uses the same).
const IRREGULAR_SEED: u64 = 1;

/// Seed of the shuffled grid's vertex order.
const SHUFFLE_SEED: u64 = 2;

/// A benchmark mesh: which one a row runs, and so what its paired ratio sets it against.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
enum MeshKind {
    /// A grid of this many vertices a side, in order.
    Grid(u32),
    /// The irregular mesh of (about) this many vertices.
    Irregular(u32),
    /// The grid of this many vertices a side, numbered at random after it is generated.
    Shuffled(u32),
}

impl MeshKind {
    /// How the tables name it.
    fn name(self) -> String {
        match self {
            Self::Grid(n) => format!("grid {n}^2"),
            Self::Irregular(vertices) => format!("irregular {vertices}"),
            Self::Shuffled(n) => format!("grid {n}^2 shuffled"),
        }
    }

    /// The mesh generated.
    fn section(self) -> MeshSection {
        match self {
            Self::Grid(n) | Self::Shuffled(n) => MeshSection::unit_grid(n, n),
            Self::Irregular(vertices) => MeshSection::unit_irregular(vertices, IRREGULAR_SEED),
        }
    }

    /// The vertices asked of the generator.
    fn vertices(self) -> u32 {
        match self {
            Self::Grid(n) | Self::Shuffled(n) => n * n,
            Self::Irregular(vertices) => vertices,
        }
    }
}

/// The benchmark scene; its dt may exceed the conservative stability bound on irregular meshes
/// (valence up to 12), which the table marks rather than refuses, since the workload is fixed.
fn benchmark_scene(workload: MeshKind) -> anyhow::Result<Scene> {
    let name = Path::new("bench");
    let scene = SceneFile::benchmark(workload.section(), workload.vertices()).build(name, true)?;
    let actual = scene.model.vertex_count() as u32;
    let shuffled = matches!(workload, MeshKind::Shuffled(_));
    if actual == workload.vertices() && !shuffled {
        return Ok(scene);
    }
    // A generator may make a few vertices fewer than asked; m = 1/N needs the real N.
    let mesh = if shuffled {
        scene.mesh.shuffled(SHUFFLE_SEED)
    } else {
        scene.mesh
    };
    let file = SceneFile::benchmark(workload.section(), actual);
    Ok(file.build_with_mesh(mesh, Vec::new(), name, true)?)
}

/// Fused steps per timing sample.
const STEPS_PER_SAMPLE: u32 = 10;

fn median(samples: Vec<Duration>) -> f64 {
    median_ms(samples.iter().map(|d| d.as_secs_f64() * 1e3).collect())
}

/// The middle value (the upper of the two middle ones for an even count); 0 for none.
fn median_ms(mut values: Vec<f64>) -> f64 {
    values.sort_unstable_by(f64::total_cmp);
    values.get(values.len() / 2).copied().unwrap_or(0.0)
}

/// Per-phase medians of phase-separated steps, ms.
struct PhaseMedians {
    force_calculation: f64,
    force_accumulation: Option<f64>,
    integration: f64,
    collision: Option<f64>,
    self_collision: Option<SelfCollisionParts>,
    total: f64,
}

/// Medians of the self-collision's parts over the phase-timed steps, ms (see
/// `hooke_core::selfcollide::PartTimes`). Each part's median is taken on its own, so they
/// need not add up to `whole`.
#[derive(Debug, Serialize)]
struct SelfCollisionParts {
    measuring: f64,
    pairs: f64,
    covering: f64,
    sorting: f64,
    window_tests: f64,
    moving: f64,
    whole: f64,
}

impl PhaseMedians {
    fn of(phases: &[PhaseTimes], accumulates: bool, collides: bool) -> Self {
        let of =
            |phase: &dyn Fn(&PhaseTimes) -> Duration| median(phases.iter().map(phase).collect());
        let timed_parts = !phases.is_empty() && phases.iter().all(|p| p.self_collision.is_some());
        let part = |part: fn(&PartTimes) -> Duration| {
            of(&|p: &PhaseTimes| p.self_collision.as_ref().map(part).unwrap_or_default())
        };
        Self {
            force_calculation: of(&|p| p.force_calculation),
            force_accumulation: accumulates
                .then(|| of(&|p| p.force_accumulation.unwrap_or_default())),
            integration: of(&|p| p.integration),
            collision: collides.then(|| of(&|p| p.collision)),
            self_collision: timed_parts.then(|| SelfCollisionParts {
                measuring: part(|p| p.measuring),
                pairs: part(|p| p.pairs),
                covering: part(|p| p.covering),
                sorting: part(|p| p.sorting),
                window_tests: part(|p| p.window_tests),
                moving: part(|p| p.moving),
                whole: part(PartTimes::total),
            }),
            total: of(&PhaseTimes::total),
        }
    }
}

/// Median time per step of `--steps` steps, timed in batches as `hooke run` steps (a lone
/// step would also time waking the CPU's worker threads). On the GPU each batch includes one
/// small status read-back, as every `hooke run` batch has.
fn median_step_ms(simulation: &mut Simulation, args: &BenchArgs) -> anyhow::Result<f64> {
    let batches = args.steps.div_ceil(STEPS_PER_SAMPLE);
    let mut totals = Vec::with_capacity(batches as usize);
    for _ in 0..batches {
        let start = Instant::now();
        simulation.step(STEPS_PER_SAMPLE)?;
        totals.push(start.elapsed() / STEPS_PER_SAMPLE);
    }
    Ok(median(totals))
}

/// One row: the rounds' fused-step medians, then `--steps` phase-timed steps, on any solver.
fn measure(
    timed: &mut Timed,
    scene: &Scene,
    args: &BenchArgs,
    copy_pool: &rayon::ThreadPool,
) -> anyhow::Result<Row> {
    let total_ms = median_ms(timed.rounds_ms.clone());
    // The GPU records them back to back, 10 to a submission, as the fused steps run.
    let (phases, source) = timed.simulation.steps_timed(args.steps)?;
    let simulation = &mut timed.simulation;
    let timing = match source {
        TimingSource::Timestamps => {
            format!("gpu timestamps, {TIMED_STEPS_PER_SUBMISSION} steps a submission")
        }
        TimingSource::WallClock => "wall clock".to_owned(),
    };
    // Which phases have passes of their own: the GPU's gather integrates in its force pass,
    // and its atomic accumulations sum there; the CPU times its phases apart.
    let (backend, method, threads, accumulates, integrates, bytes_per_step, bandwidth, sweep) =
        match (simulation.choice(), simulation.memory()) {
            (SolverChoice::Gpu(method), MemoryReport::Gpu(memory)) => (
                "gpu",
                method.name(),
                0,
                phases.iter().any(|p| p.force_accumulation.is_some()),
                method != GpuMethod::Gather,
                memory.table_1() as usize,
                None,
                None,
            ),
            (SolverChoice::Cpu(options), _) => {
                let solver = simulation
                    .cpu_solver()
                    .context("a cpu choice runs the cpu solver")?;
                let bytes = solver.bytes_per_step();
                (
                    "cpu",
                    options.method.name().to_owned(),
                    solver.threads(),
                    options.method == Method::Scatter,
                    true,
                    bytes,
                    Some(copy_bandwidth(bytes, copy_pool)),
                    Some(solver.steps_per_sweep()),
                )
            }
            (choice, _) => anyhow::bail!("hooke bench does not time {}", choice.name()),
        };
    let medians = PhaseMedians::of(&phases, accumulates, scene.model.collision.any());
    let dispatches_per_step = simulation
        .gpu_solver_mut()
        .map(|solver| solver.dispatches_per_step());
    Ok(Row {
        mesh: timed.name.clone(),
        kind: timed.kind,
        self_collision: timed.self_collision,
        vertices: scene.model.vertex_count(),
        springs: scene.model.spring_count(),
        backend,
        method,
        threads,
        phase_timing: timing,
        force_calculation_ms: medians.force_calculation,
        force_accumulation_ms: medians.force_accumulation,
        integration_ms: integrates.then_some(medians.integration),
        collision_ms: medians.collision,
        self_collision_parts_ms: medians.self_collision,
        phased_total_ms: medians.total,
        total_ms,
        total_rounds_ms: timed.rounds_ms.clone(),
        // Set once every row's phases are timed (see `run`).
        exploded: None,
        springs_per_second: scene.model.spring_count() as f64 / (total_ms * 1e-3),
        bytes_per_step,
        dispatches_per_step,
        copy_bandwidth_gb_per_s: bandwidth.map(|b| b / 1e9),
        bandwidth_floor_ms: bandwidth.map(|b| 1e3 * bytes_per_step as f64 / b),
        dt_above_stability_bound: scene.material.dt > scene.max_stable_dt,
        steps_per_sweep: sweep,
    })
}

/// One row's fused step against another's, per spring, round by round.
#[derive(Debug, Serialize)]
struct Paired {
    mesh: String,
    backend: &'static str,
    method: String,
    /// The other row's mesh.
    against: String,
    /// Median of the rounds' ratios.
    ratio: f64,
    /// Each round's ratio, in the order run.
    rounds: Vec<f64>,
}

/// The row each row is set against, if any: the same mesh without self-collision for a row
/// with it; the grid of the same vertex count for the irregular mesh and the shuffled grid;
/// the smallest grid for a larger one. Always the same backend and method.
fn reference_of<'a>(row: &Row, rows: &'a [Row]) -> Option<&'a Row> {
    let alike = |other: &&Row| {
        other.backend == row.backend && other.method == row.method && other.self_collision.is_none()
    };
    let mut candidates = rows.iter().filter(alike);
    if row.self_collision.is_some() {
        return candidates.find(|other| other.kind == row.kind);
    }
    let grid_side = |other: &Row| match other.kind {
        MeshKind::Grid(n) => Some(n),
        _ => None,
    };
    match row.kind {
        MeshKind::Irregular(vertices) => {
            candidates.find(|other| grid_side(other).is_some_and(|n| n * n == vertices))
        }
        MeshKind::Shuffled(side) => candidates.find(|other| other.kind == MeshKind::Grid(side)),
        MeshKind::Grid(side) => candidates
            .filter(|other| grid_side(other).is_some_and(|n| n < side))
            .min_by_key(|other| grid_side(other)),
    }
}

/// Every row that has a reference row, against it.
fn paired(rows: &[Row]) -> Vec<Paired> {
    rows.iter()
        .filter_map(|row| {
            let reference = reference_of(row, rows)?;
            let per_spring = |ms: f64, of: &Row| ms / of.springs.max(1) as f64;
            let rounds: Vec<f64> = row
                .total_rounds_ms
                .iter()
                .zip(&reference.total_rounds_ms)
                .map(|(&a, &b)| per_spring(a, row) / per_spring(b, reference))
                .collect();
            Some(Paired {
                mesh: row.mesh.clone(),
                backend: row.backend,
                method: row.method.clone(),
                against: reference.mesh.clone(),
                ratio: median_ms(rounds.clone()),
                rounds,
            })
        })
        .collect()
}

/// Copy bandwidth in bytes/s (bytes read plus bytes written) over a buffer moving `bytes` per
/// copy, with the pool's threads; the best of several repetitions.
fn copy_bandwidth(bytes: usize, pool: &rayon::ThreadPool) -> f64 {
    let words = (bytes / 2 / std::mem::size_of::<f32>()).max(1 << 16);
    let source = vec![1.0f32; words];
    let mut target = vec![0.0f32; words];
    let chunk = words.div_ceil(pool.current_num_threads() * 8).max(1024);
    let mut best = f64::INFINITY;
    for _ in 0..20 {
        let start = Instant::now();
        pool.install(|| {
            target
                .par_chunks_mut(chunk)
                .zip(source.par_chunks(chunk))
                .for_each(|(t, s)| t.copy_from_slice(s));
        });
        best = best.min(start.elapsed().as_secs_f64());
    }
    std::hint::black_box(&target);
    (2 * words * std::mem::size_of::<f32>()) as f64 / best
}

fn cpu_name() -> String {
    std::fs::read_to_string("/proc/cpuinfo")
        .ok()
        .and_then(|info| {
            info.lines()
                .find(|l| l.starts_with("model name"))
                .and_then(|l| l.split(':').nth(1))
                .map(|s| s.trim().to_owned())
        })
        .unwrap_or_else(|| std::env::consts::ARCH.to_owned())
}

fn print_report(report: &Report) {
    println!(
        "hooke bench: cpu {} ({} threads, {} SIMD){}; medians of {} steps{}",
        report.cpu,
        report.threads,
        report.simd,
        report
            .gpu
            .as_ref()
            .map(|g| format!(", gpu {g}"))
            .unwrap_or_default(),
        report.steps,
        if report.rounds > 1 {
            format!(
                "; total: the median of {} interleaved rounds (fastest-slowest round)",
                report.rounds
            )
        } else {
            String::new()
        }
    );
    let mut t = Table::new();
    t.set_header(vec![
        "mesh",
        "backend",
        "method",
        "force calc ms",
        "force accum ms",
        "integration ms",
        "collision ms",
        "sum of phases ms",
        "total ms",
        "Mspring/s",
        "bytes/step",
        "bw floor ms",
        "passes",
    ]);
    for r in &report.rows {
        let mesh = if r.dt_above_stability_bound {
            format!("{} *", r.mesh)
        } else {
            r.mesh.clone()
        };
        t.add_row(vec![
            mesh,
            r.backend.to_owned(),
            r.method.clone(),
            format!("{:.3}", r.force_calculation_ms),
            r.force_accumulation_ms
                .map_or("-".to_owned(), |a| format!("{a:.3}")),
            r.integration_ms
                .map_or("-".to_owned(), |i| format!("{i:.3}")),
            r.collision_ms.map_or("-".to_owned(), |c| format!("{c:.3}")),
            format!("{:.3}", r.phased_total_ms),
            with_range(r.total_ms, &r.total_rounds_ms, 3),
            format!("{:.0}", r.springs_per_second / 1e6),
            bytes(r.bytes_per_step),
            r.bandwidth_floor_ms
                .map_or("-".to_owned(), |f| format!("{f:.3}")),
            r.dispatches_per_step
                .map_or("-".to_owned(), |d| d.to_string()),
        ]);
    }
    println!("{}", table(t));
    print_self_collision_parts(report);
    print_paired(report);
    println!(
        "gather, and the gpu's atomic-f32 and atomic-fixed: force calc includes the per-vertex sum (no separate accumulation; gather's as in the paper's Table 2); the gpu's gather also integrates in that pass."
    );
    println!(
        "total: the fused step as `hooke run` executes it; bw floor: bytes/step over measured copy bandwidth."
    );
    if let Some(note) = sweeps_note(&report.rows) {
        println!("{note}");
    }
    if let Some(gpu) = report.rows.iter().find(|r| r.backend == "gpu") {
        println!(
            "gpu: phases from {}; total includes one status read-back per 10 steps; bytes/step is the GPU memory the method allocates; passes: compute dispatches and draws per step.",
            gpu.phase_timing
        );
    }
    for why in &report.skipped {
        println!("skipped {why}");
    }
    for row in &report.rows {
        if let Some(why) = &row.exploded {
            println!(
                "exploded: {} {} {}, found {why}: its times before may be of a state `hooke run` would have stopped at.",
                row.mesh, row.backend, row.method
            );
        }
    }
    if report.rows.iter().any(|r| r.dt_above_stability_bound) {
        println!(
            "*: the workload's dt exceeds hooke's conservative stability bound on this mesh (it ran stably here)."
        );
    }
}

/// Which rows' fused steps swept several steps at a time, and how many at most, since their
/// totals (and any ratio to them) depend on it; `None` if none did.
fn sweeps_note(rows: &[Row]) -> Option<String> {
    let swept: Vec<String> = rows
        .iter()
        .filter_map(|r| {
            let steps = r.steps_per_sweep.filter(|&s| s > 1)?;
            Some(format!("{} {} {steps}", r.mesh, r.method))
        })
        .collect();
    (!swept.is_empty()).then(|| {
        format!(
            "sweeps: steps advanced per sweep over memory at most, where nothing acts between them: {}.",
            swept.join(", ")
        )
    })
}

/// `median` with `digits` decimals, followed by the smallest and largest of `rounds` where
/// there are several.
fn with_range(median: f64, rounds: &[f64], digits: usize) -> String {
    if rounds.len() < 2 {
        return format!("{median:.digits$}");
    }
    let smallest = rounds.iter().copied().fold(f64::INFINITY, f64::min);
    let largest = rounds.iter().copied().fold(f64::NEG_INFINITY, f64::max);
    format!("{median:.digits$} ({smallest:.digits$}-{largest:.digits$})")
}

/// The self-collision's parts, in a table of their own, where any row has them.
fn print_self_collision_parts(report: &Report) {
    let rows: Vec<(&Row, &SelfCollisionParts)> = report
        .rows
        .iter()
        .filter_map(|r| Some((r, r.self_collision_parts_ms.as_ref()?)))
        .collect();
    if rows.is_empty() {
        return;
    }
    let mut t = Table::new();
    t.set_header(vec![
        "mesh",
        "backend",
        "method",
        "proof: measuring ms",
        "proof: pairs ms",
        "covering ms",
        "sorting ms",
        "window tests ms",
        "moving ms",
        "self-collision ms",
    ]);
    for (r, parts) in rows {
        let ms = |v: f64| format!("{v:.3}");
        t.add_row(vec![
            r.mesh.clone(),
            r.backend.to_owned(),
            r.method.clone(),
            ms(parts.measuring),
            ms(parts.pairs),
            ms(parts.covering),
            ms(parts.sorting),
            ms(parts.window_tests),
            ms(parts.moving),
            ms(parts.whole),
        ]);
    }
    println!(
        "self-collision by part: medians over the phase-timed steps, each part's on its own (part of collision ms above)"
    );
    println!("{}", table(t));
}

/// The paired ratios, in a table of their own.
fn print_paired(report: &Report) {
    if report.paired.is_empty() {
        return;
    }
    let mut t = Table::new();
    t.set_header(vec![
        "mesh",
        "backend",
        "method",
        "against",
        "ratio per spring",
    ]);
    for p in &report.paired {
        t.add_row(vec![
            p.mesh.clone(),
            p.backend.to_owned(),
            p.method.clone(),
            p.against.clone(),
            with_range(p.ratio, &p.rounds, 2),
        ]);
    }
    println!(
        "paired: each row's fused step per spring over another's, taken round by round in the same rounds (median, and range over rounds)"
    );
    println!("{}", table(t));
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A cpu gather row of `mesh` with `springs` springs and these rounds.
    fn row(
        mesh: &str,
        kind: MeshKind,
        self_collision: Option<u32>,
        springs: usize,
        rounds: &[f64],
    ) -> Row {
        Row {
            mesh: mesh.to_owned(),
            kind,
            self_collision,
            vertices: 0,
            springs,
            backend: "cpu",
            method: "gather".to_owned(),
            threads: 2,
            phase_timing: "wall clock".to_owned(),
            force_calculation_ms: 0.0,
            force_accumulation_ms: None,
            integration_ms: None,
            collision_ms: None,
            self_collision_parts_ms: None,
            phased_total_ms: 0.0,
            total_ms: median_ms(rounds.to_vec()),
            total_rounds_ms: rounds.to_vec(),
            exploded: None,
            springs_per_second: 0.0,
            bytes_per_step: 0,
            dispatches_per_step: None,
            copy_bandwidth_gb_per_s: None,
            bandwidth_floor_ms: None,
            dt_above_stability_bound: false,
            steps_per_sweep: Some(1),
        }
    }

    #[test]
    fn rows_pair_round_by_round_with_their_reference_per_spring() {
        let rows = vec![
            row("grid 16^2", MeshKind::Grid(16), None, 100, &[1.0, 2.0, 1.0]),
            row("grid 32^2", MeshKind::Grid(32), None, 400, &[4.4, 8.0, 4.0]),
            row(
                "grid 64^2",
                MeshKind::Grid(64),
                None,
                1600,
                &[16.0, 16.0, 16.0],
            ),
            row(
                "irregular 256",
                MeshKind::Irregular(256),
                None,
                100,
                &[1.3, 2.0, 1.5],
            ),
            row(
                "irregular 999",
                MeshKind::Irregular(999),
                None,
                100,
                &[1.0, 1.0, 1.0],
            ),
            row(
                "grid 16^2 shuffled",
                MeshKind::Shuffled(16),
                None,
                100,
                &[1.0, 2.2, 1.1],
            ),
            row(
                "grid 32^2 + self-collision 4",
                MeshKind::Grid(32),
                Some(4),
                400,
                &[13.2, 16.0, 16.0],
            ),
        ];
        let found = paired(&rows);
        let by_mesh = |mesh: &str| found.iter().find(|p| p.mesh == mesh);
        let close = |a: &[f64], b: &[f64]| a.iter().zip(b).all(|(x, y)| (x - y).abs() < 1e-12);
        // The smallest grid and the irregular mesh with no grid of its size have none.
        assert!(by_mesh("grid 16^2").is_none() && by_mesh("irregular 999").is_none());
        let larger = by_mesh("grid 32^2").expect("paired");
        assert_eq!(larger.against, "grid 16^2");
        assert!(close(&larger.rounds, &[1.1, 1.0, 1.0]), "{larger:?}");
        assert!((larger.ratio - 1.0).abs() < 1e-12);
        // Against the smallest grid, not the next one.
        assert_eq!(by_mesh("grid 64^2").expect("paired").against, "grid 16^2");
        let irregular = by_mesh("irregular 256").expect("paired");
        assert_eq!(irregular.against, "grid 16^2");
        assert!(close(&irregular.rounds, &[1.3, 1.0, 1.5]) && irregular.ratio == 1.3);
        assert_eq!(
            by_mesh("grid 16^2 shuffled").expect("paired").against,
            "grid 16^2"
        );
        let contact = by_mesh("grid 32^2 + self-collision 4").expect("paired");
        assert_eq!(contact.against, "grid 32^2");
        assert!(close(&contact.rounds, &[3.0, 2.0, 4.0]) && contact.ratio == 3.0);
    }

    #[test]
    fn only_an_accumulation_out_of_range_skips_a_method() {
        let overflow = || SimError::Overflow {
            step: 280,
            detail: "a spring force exceeded the fixed-point range".into(),
        };
        let from_engine = anyhow::Error::from(EngineError::Simulation(overflow()))
            .context("grid 256^2, gpu scatter/atomic-fixed");
        assert!(out_of_range(&from_engine));
        assert!(out_of_range(&anyhow::Error::from(overflow())));
        let unstable = EngineError::Simulation(SimError::NonFinite { step: 3, vertex: 7 });
        assert!(!out_of_range(&anyhow::Error::from(unstable)));
    }

    #[test]
    fn an_exploded_state_is_noted_and_a_non_finite_one_is_an_error() {
        // The workload as built is healthy; with a vertex pulled 10 m away (100 rest lengths
        // are 6.7 m at 16^2) it has exploded; with one at infinity it is not finite.
        let scene = benchmark_scene(MeshKind::Grid(16)).expect("scene");
        let choice = SolverChoice::Cpu(CpuOptions::default());
        let mut simulation = Simulation::from_scene(&scene, choice, None).expect("cpu");
        simulation.step(10).expect("steps");
        assert_eq!(explosion(&simulation), Ok(None));
        let healthy = simulation.state().expect("state");
        let mut state = healthy.clone();
        state.positions[5].y -= 10.0;
        simulation.set_state(&state);
        let why = explosion(&simulation).expect("readable").expect("exploded");
        assert!(why.starts_with("step 10: the simulation exploded"), "{why}");
        let mut entry = Timed {
            name: "grid 16^2".to_owned(),
            kind: MeshKind::Grid(16),
            self_collision: None,
            scene: 0,
            simulation,
            rounds_ms: Vec::new(),
            exploded: None,
        };
        entry.note_explosion("after round 2").expect("noted");
        let noted = entry.exploded.clone().expect("noted");
        assert!(noted.starts_with("after round 2 (step 10:"), "{noted}");
        // The first explosion stays noted.
        entry.simulation.set_state(&healthy);
        entry.note_explosion("after round 3").expect("noted");
        assert_eq!(entry.exploded, Some(noted));
        state.positions[5].y = f64::INFINITY;
        entry.simulation.set_state(&state);
        assert!(matches!(
            explosion(&entry.simulation),
            Err(SimError::NonFinite { vertex: 5, .. })
        ));
    }
}
