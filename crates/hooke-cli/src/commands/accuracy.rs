//! `hooke accuracy`: every method and accumulation precision against the float64 reference.
//!
//! After `--steps` steps from the scene's initial state: the relative L2 error of all positions,
//! the largest vertex error, and the change of total energy `E(N) - E(0)` in joules next to the
//! reference's own (damping makes both negative; a blow-up makes one large). This is the paper's precision finding measured: 8-bit accumulation is not
//! enough, 16-bit comes close, 32-bit matches.

use std::path::PathBuf;
use std::sync::Arc;

use clap::Args;
use comfy_table::Table;
use hooke::{Simulation, SolverChoice};
use hooke_core::State;
use hooke_core::diagnostics::{energy, relative_l2};
use hooke_core::scene::Scene;
use hooke_cpu::{CpuOptions, Method};
use hooke_gpu::GpuMethod;
use serde::Serialize;

use crate::format::{OutputFormat, table};
use crate::scene_loading::load_scene;
use crate::solvers::open_gpu;

#[derive(Debug, Args)]
pub struct AccuracyArgs {
    /// Scene file (TOML).
    pub scene: PathBuf,
    /// Steps to run before comparing.
    #[arg(long, default_value_t = 100)]
    pub steps: u32,
    /// Skip the GPU methods.
    #[arg(long)]
    pub no_gpu: bool,
    /// Run even if dt exceeds the stability bound.
    #[arg(long)]
    pub allow_unstable: bool,
    #[arg(long, value_enum, default_value_t = OutputFormat::Table)]
    pub format: OutputFormat,
}

#[derive(Debug, Serialize)]
struct Row {
    solver: String,
    relative_l2_error: f64,
    max_vertex_error_m: f64,
    /// E(N) - E(0), J.
    energy_change_j: f64,
    /// Why the method did not produce a result (unsupported, blew up), if it did not.
    failure: Option<String>,
}

#[derive(Debug, Serialize)]
struct Report {
    scene: String,
    vertices: usize,
    steps: u32,
    reference_energy_change_j: f64,
    rows: Vec<Row>,
}

pub fn run(args: &AccuracyArgs) -> anyhow::Result<()> {
    let scene = load_scene(&args.scene, args.allow_unstable)?;
    let mut reference = Simulation::from_scene(&scene, SolverChoice::Reference, None)?;
    let initial = reference.state()?;
    reference.step(args.steps)?;
    let expected = reference.state()?;
    let e0 = energy(&scene.model, &initial, &scene.material).total();
    let drift = |state: &State| energy(&scene.model, state, &scene.material).total() - e0;
    let mut solvers: Vec<(String, anyhow::Result<Simulation>)> = Method::ALL
        .iter()
        .map(|&method| {
            let choice = SolverChoice::Cpu(CpuOptions {
                method,
                ..Default::default()
            });
            let simulation = Simulation::from_scene(&scene, choice, None);
            (choice.name(), simulation.map_err(anyhow::Error::from))
        })
        .collect();
    if !args.no_gpu {
        match open_gpu() {
            Ok(context) => solvers.extend(GpuMethod::all().into_iter().map(|method| {
                let choice = SolverChoice::Gpu(method);
                let simulation = Simulation::from_scene(&scene, choice, Some(Arc::clone(&context)));
                (choice.name(), simulation.map_err(anyhow::Error::from))
            })),
            Err(error) => eprintln!("gpu methods skipped: {error:#}"),
        }
    }
    let rows = solvers
        .into_iter()
        .map(|(name, solver)| measure(name, solver, args.steps, &expected, &drift))
        .collect();
    let report = Report {
        scene: scene.name.clone(),
        vertices: scene.model.vertex_count(),
        steps: args.steps,
        reference_energy_change_j: drift(&expected),
        rows,
    };
    match args.format {
        OutputFormat::Json => println!("{}", serde_json::to_string_pretty(&report)?),
        OutputFormat::Table => print_report(&report, &scene),
    }
    Ok(())
}

fn measure(
    name: String,
    solver: anyhow::Result<Simulation>,
    steps: u32,
    expected: &State,
    drift: &dyn Fn(&State) -> f64,
) -> Row {
    let failed = |failure: String| Row {
        solver: name.clone(),
        relative_l2_error: f64::NAN,
        max_vertex_error_m: f64::NAN,
        energy_change_j: f64::NAN,
        failure: Some(failure),
    };
    let mut solver = match solver {
        Ok(solver) => solver,
        Err(error) => return failed(format!("{error:#}")),
    };
    if let Err(error) = solver.step(steps) {
        return failed(error.to_string());
    }
    let state = match solver.state() {
        Ok(state) => state,
        Err(error) => return failed(error.to_string()),
    };
    let errors: Vec<f64> = state
        .positions
        .iter()
        .zip(&expected.positions)
        .map(|(p, q)| p.distance(*q))
        .collect();
    Row {
        relative_l2_error: relative_l2(&state.positions, &expected.positions),
        max_vertex_error_m: errors.iter().copied().fold(0.0, f64::max),
        energy_change_j: drift(&state),
        failure: None,
        solver: name,
    }
}

fn print_report(report: &Report, scene: &Scene) {
    println!(
        "{}: {} vertices, {} steps of {:.3e} s against the float64 reference (its energy change: {:+.4e} J)",
        report.scene,
        report.vertices,
        report.steps,
        scene.material.dt,
        report.reference_energy_change_j
    );
    let mut t = Table::new();
    t.set_header(vec![
        "solver",
        "relative L2 error",
        "max vertex error m",
        "energy change J",
    ]);
    for r in &report.rows {
        match &r.failure {
            Some(failure) => t.add_row(vec![
                r.solver.clone(),
                format!("- ({failure})"),
                "-".into(),
                "-".into(),
            ]),
            None => t.add_row(vec![
                r.solver.clone(),
                format!("{:.2e}", r.relative_l2_error),
                format!("{:.2e}", r.max_vertex_error_m),
                format!("{:+.4e}", r.energy_change_j),
            ]),
        };
    }
    println!("{}", table(t));
}
