//! The Rust side of the Python overhead benchmark (`crates/hooke-py/bench/step_overhead.py`):
//! a scene on the CPU solver, stepped in batches as a Python loop would, timed per step.
//!
//!     cargo run --release -p hooke --example step_timing -- SCENE STEPS BATCH
//!
//! Prints one line: `ms/step X`.

use std::path::PathBuf;
use std::time::Instant;

use hooke::{Simulation, SolverChoice};
use hooke_core::scene::SceneFile;

fn main() -> Result<(), Box<dyn std::error::Error>> {
    let mut args = std::env::args().skip(1);
    let scene_path = PathBuf::from(args.next().ok_or("usage: step_timing SCENE STEPS BATCH")?);
    let steps: u32 = args.next().ok_or("STEPS missing")?.parse()?;
    let batch: u32 = args.next().ok_or("BATCH missing")?.parse()?;
    let scene = SceneFile::load(&scene_path)?.build(&scene_path, true)?;
    let choice = SolverChoice::from_names("cpu", Some("gather"), None, None)?;
    let mut simulation = Simulation::from_scene(&scene, choice, None)?;
    simulation.step(batch)?; // warm-up, as the Python side does
    let start = Instant::now();
    for _ in 0..steps / batch {
        simulation.step(batch)?;
    }
    let elapsed = start.elapsed().as_secs_f64();
    println!(
        "ms/step {:.6}",
        elapsed * 1e3 / f64::from(steps / batch * batch)
    );
    Ok(())
}
