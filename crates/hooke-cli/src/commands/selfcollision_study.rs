//! `hooke selfcollision-study`: what the approximate self-collision (binning over K staggered
//! grids) misses and costs, against the exact hash-grid search (paper Section 5: "the majority
//! of self collisions can be detected", and misses grow with the time step and crowded cells).
//!
//! The scene runs on the CPU solver with its self-collision. At `--samples` moments the state
//! is advanced one step *without* self-collision: those positions are what the pass sees, and
//! on them the exact search (every unjoined pair closer than the distance) is compared with what
//! each setting's binning finds. A miss is an exact pair no grid's window found. The cost is the
//! CPU time of one full pass (keys, sort, window, correction) on the same positions.
//!
//! The time-step table reruns the scene to the same simulated time at other time steps and
//! counts, at the end, the unjoined pairs closer than half the distance ("interpenetrating"),
//! with self-collision on and off.

use std::path::PathBuf;
use std::time::Instant;

use clap::Args;
use comfy_table::Table;
use glam::Vec3;
use hooke::{Simulation, SolverChoice};
use hooke_core::scene::Scene;
use hooke_core::selfcollide::{self, SelfCollision};
use hooke_core::{Material, State};
use hooke_cpu::CpuOptions;
use serde::Serialize;

use crate::format::{OutputFormat, table};
use crate::scene_loading::load_scene;

#[derive(Debug, Args)]
pub struct StudyArgs {
    /// Scene file (TOML); its `[self_collision]` section is the baseline setting.
    pub scene: PathBuf,
    /// Staggered grid counts K to compare.
    #[arg(long, value_delimiter = ',', default_value = "1,2,4,8")]
    pub grids: Vec<u32>,
    /// Cell sizes to compare, in multiples of the self-collision distance.
    #[arg(long, value_delimiter = ',', default_value = "1,2,4")]
    pub cell_sizes: Vec<f64>,
    /// Time steps to compare, in multiples of the scene's dt (kept within the stability bound
    /// unless --allow-unstable).
    #[arg(long, value_delimiter = ',', default_value = "0.25,0.5,1")]
    pub dt_scales: Vec<f64>,
    /// Steps to run; defaults to the scene's.
    #[arg(long)]
    pub steps: Option<u64>,
    /// Moments at which detection is compared.
    #[arg(long, default_value_t = 8)]
    pub samples: u32,
    #[arg(long)]
    pub allow_unstable: bool,
    #[arg(long, value_enum, default_value_t = OutputFormat::Table)]
    pub format: OutputFormat,
}

#[derive(Debug, Serialize)]
struct SettingRow {
    grids: u32,
    cell_size_m: f64,
    window: u32,
    /// Exact pairs over all samples.
    exact_pairs: usize,
    missed_share: f64,
    /// Mean vertices per occupied cell of the first grid.
    vertices_per_cell: f64,
    /// Median CPU time of one pass, ms.
    cost_ms: f64,
}

#[derive(Debug, Serialize)]
struct StepRow {
    dt_s: f64,
    steps: u64,
    /// Missed share of the baseline setting over the samples.
    missed_share: f64,
    interpenetrating_with: usize,
    interpenetrating_without: usize,
}

#[derive(Debug, Serialize)]
struct Report {
    scene: String,
    vertices: usize,
    distance_m: f64,
    settings: Vec<SettingRow>,
    time_steps: Vec<StepRow>,
}

pub fn run(args: &StudyArgs) -> anyhow::Result<()> {
    let scene = load_scene(&args.scene, args.allow_unstable)?;
    let baseline = scene
        .model
        .collision
        .self_collision
        .unwrap_or_else(|| SelfCollision::for_model(&scene.model));
    let steps = args.steps.unwrap_or(scene.steps);
    anyhow::ensure!(args.samples > 0, "--samples must be at least 1");
    for &k in &args.grids {
        anyhow::ensure!(
            (1..=selfcollide::MAX_GRIDS).contains(&k),
            "--grids: {k} is outside 1..={}",
            selfcollide::MAX_GRIDS
        );
    }
    for &c in args.cell_sizes.iter().chain(&args.dt_scales) {
        anyhow::ensure!(
            c > 0.0 && c.is_finite(),
            "--cell-sizes and --dt-scales take positive numbers, found {c}"
        );
    }

    let samples = sample_positions(&scene, &scene.material, baseline, steps, args.samples)?;
    let mut settings = Vec::new();
    for &grids in &args.grids {
        for &cells in &args.cell_sizes {
            let config = SelfCollision {
                grids,
                cell_size: cells * baseline.distance,
                ..baseline
            };
            settings.push(measure_setting(&scene, &samples, &config));
        }
    }

    let mut time_steps = Vec::new();
    for &scale in &args.dt_scales {
        let dt = scene.material.dt * scale;
        if dt > scene.max_stable_dt && !args.allow_unstable {
            eprintln!(
                "dt scale {scale}: {dt:.3e} s exceeds the stability bound {:.3e} s; skipped (--allow-unstable runs it)",
                scene.max_stable_dt
            );
            continue;
        }
        let scaled_steps = (steps as f64 / scale).round() as u64;
        let material = Material {
            dt,
            ..scene.material
        };
        let samples = sample_positions(&scene, &material, baseline, scaled_steps, args.samples)?;
        let exact: usize = samples.iter().map(|s| s.exact.len()).sum();
        let missed: f64 = samples
            .iter()
            .map(|s| {
                let found =
                    selfcollide::approximate_pairs(&s.positions, &scene.model.adjacency, &baseline);
                selfcollide::missed_share(&s.exact, &found) * s.exact.len() as f64
            })
            .sum();
        let count_at_end = |config: Option<SelfCollision>| -> anyhow::Result<usize> {
            let state = run_cpu(&scene, &material, config, scaled_steps)?;
            Ok(interpenetrating(&scene, &state, baseline.distance))
        };
        time_steps.push(StepRow {
            dt_s: dt,
            steps: scaled_steps,
            missed_share: if exact == 0 {
                0.0
            } else {
                missed / exact as f64
            },
            interpenetrating_with: count_at_end(Some(baseline))?,
            interpenetrating_without: count_at_end(None)?,
        });
    }

    let report = Report {
        scene: scene.name.clone(),
        vertices: scene.model.vertex_count(),
        distance_m: baseline.distance,
        settings,
        time_steps,
    };
    match args.format {
        OutputFormat::Json => println!("{}", serde_json::to_string_pretty(&report)?),
        OutputFormat::Table => print_report(&report, &scene, steps, args.samples),
    }
    Ok(())
}

/// Positions the self-collision pass sees at one moment, and the exact pairs among them.
struct Sample {
    positions: Vec<Vec3>,
    exact: Vec<(u32, u32)>,
}

/// The scene on the CPU solver under `material`, with self-collision `config`.
fn cpu_simulation(
    scene: &Scene,
    material: &Material,
    config: Option<SelfCollision>,
) -> anyhow::Result<Simulation> {
    let choice = SolverChoice::Cpu(CpuOptions::default());
    let mut simulation = Simulation::from_scene(scene, choice, None)?;
    simulation.set_material(*material)?;
    simulation.set_self_collision(config)?;
    Ok(simulation)
}

fn run_cpu(
    scene: &Scene,
    material: &Material,
    config: Option<SelfCollision>,
    steps: u64,
) -> anyhow::Result<State> {
    let mut simulation = cpu_simulation(scene, material, config)?;
    step_in_batches(&mut simulation, steps)?;
    Ok(simulation.state()?)
}

fn step_in_batches(simulation: &mut Simulation, steps: u64) -> anyhow::Result<()> {
    let mut left = steps;
    while left > 0 {
        let batch = left.min(u64::from(u32::MAX)) as u32;
        simulation.step(batch)?;
        left -= u64::from(batch);
    }
    Ok(())
}

/// Runs with `config` and, at `count` evenly spaced moments, takes one step without
/// self-collision from the current state.
fn sample_positions(
    scene: &Scene,
    material: &Material,
    config: SelfCollision,
    steps: u64,
    count: u32,
) -> anyhow::Result<Vec<Sample>> {
    let mut solver = cpu_simulation(scene, material, Some(config))?;
    let mut probe = cpu_simulation(scene, material, None)?;
    let mut samples = Vec::new();
    let mut done = 0;
    for k in 1..=u64::from(count) {
        let target = steps * k / u64::from(count);
        step_in_batches(&mut solver, target - done)?;
        done = target;
        probe.set_state(&solver.state()?);
        probe.step(1)?;
        let positions: Vec<Vec3> = probe
            .state()?
            .positions
            .iter()
            .map(|p| p.as_vec3())
            .collect();
        let exact = selfcollide::exact_pairs(&positions, &scene.model.adjacency, config.distance);
        samples.push(Sample { positions, exact });
    }
    Ok(samples)
}

fn measure_setting(scene: &Scene, samples: &[Sample], config: &SelfCollision) -> SettingRow {
    let adjacency = &scene.model.adjacency;
    let weights = selfcollide::inverse_masses(&scene.model);
    let mut exact_pairs = 0;
    let mut missed = 0.0;
    let mut costs = Vec::new();
    let mut occupancy = Vec::new();
    for sample in samples {
        let found = selfcollide::approximate_pairs(&sample.positions, adjacency, config);
        exact_pairs += sample.exact.len();
        missed += selfcollide::missed_share(&sample.exact, &found) * sample.exact.len() as f64;
        let mut positions = sample.positions.clone();
        let start = Instant::now();
        selfcollide::resolve(&mut positions, &weights, adjacency, config);
        costs.push(start.elapsed().as_secs_f64() * 1e3);
        occupancy.push(selfcollide::vertices_per_cell(&sample.positions, config));
    }
    costs.sort_by(f64::total_cmp);
    SettingRow {
        grids: config.grids,
        cell_size_m: config.cell_size,
        window: config.window,
        exact_pairs,
        missed_share: if exact_pairs == 0 {
            0.0
        } else {
            missed / exact_pairs as f64
        },
        vertices_per_cell: occupancy.iter().sum::<f64>() / occupancy.len() as f64,
        cost_ms: costs[costs.len() / 2],
    }
}

/// Unjoined vertex pairs closer than half the self-collision distance.
fn interpenetrating(scene: &Scene, state: &State, distance: f64) -> usize {
    let positions: Vec<Vec3> = state.positions.iter().map(|p| p.as_vec3()).collect();
    selfcollide::exact_pairs(&positions, &scene.model.adjacency, 0.5 * distance).len()
}

fn print_report(report: &Report, scene: &Scene, steps: u64, samples: u32) {
    println!(
        "{}: {} vertices, distance {:.4} m, {steps} steps of {:.3e} s, {samples} samples; exact search: hash grid, 27 cells",
        report.scene, report.vertices, report.distance_m, scene.material.dt
    );
    let mut t = Table::new();
    t.set_header(vec![
        "grids K",
        "cell m",
        "window",
        "exact pairs",
        "missed",
        "vertices/cell",
        "cpu ms/pass",
    ]);
    for r in &report.settings {
        t.add_row(vec![
            r.grids.to_string(),
            format!("{:.4}", r.cell_size_m),
            r.window.to_string(),
            r.exact_pairs.to_string(),
            format!("{:.1}%", 100.0 * r.missed_share),
            format!("{:.2}", r.vertices_per_cell),
            format!("{:.3}", r.cost_ms),
        ]);
    }
    println!("{}", table(t));
    if report.time_steps.is_empty() {
        return;
    }
    println!(
        "\nsame simulated time at other time steps; interpenetrating = unjoined pairs closer than {:.4} m at the end",
        0.5 * report.distance_m
    );
    let mut t = Table::new();
    t.set_header(vec![
        "dt s",
        "steps",
        "missed",
        "interpenetrating, self-collision on",
        "off",
    ]);
    for r in &report.time_steps {
        t.add_row(vec![
            format!("{:.3e}", r.dt_s),
            r.steps.to_string(),
            format!("{:.1}%", 100.0 * r.missed_share),
            r.interpenetrating_with.to_string(),
            r.interpenetrating_without.to_string(),
        ]);
    }
    println!("{}", table(t));
}
