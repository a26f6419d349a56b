//! The `hooke` command: simulate, inspect and benchmark mass-spring scenes.

mod commands;
mod format;
mod scene_loading;
mod solvers;
mod viewer;

use std::process::ExitCode;

use clap::{Parser, Subcommand};

/// hooke: interactive mass-spring simulation of deformable surfaces (Georgii & Westermann).
#[derive(Debug, Parser)]
#[command(version, about)]
struct Cli {
    #[command(subcommand)]
    command: Command,
}

#[derive(Debug, Subcommand)]
enum Command {
    /// Simulate a scene and write frames (binary PLY), the final state and a summary.
    Run(commands::run::RunArgs),
    /// Show a scene's mesh, valences, stable time step and memory per method.
    Info(commands::info::InfoArgs),
    /// Time gather and scatter on the benchmark workload (the paper's Table 2).
    Bench(commands::bench::BenchArgs),
    /// Compare every method and accumulation precision with the float64 reference.
    Accuracy(commands::accuracy::AccuracyArgs),
    /// Measure what approximate self-collision misses and costs against an exact search.
    SelfcollisionStudy(commands::selfcollision_study::StudyArgs),
    /// Simulate on the GPU and draw offscreen: PNG frames, one PNG, or an MP4 (with ffmpeg).
    Render(commands::render::RenderArgs),
    /// Open the interactive viewer: drag the cloth, change parameters live.
    View(viewer::ViewArgs),
}

fn main() -> ExitCode {
    let result = match Cli::parse().command {
        Command::Run(args) => commands::run::run(&args),
        Command::Info(args) => commands::info::run(&args),
        Command::Bench(args) => commands::bench::run(&args),
        Command::Accuracy(args) => commands::accuracy::run(&args),
        Command::SelfcollisionStudy(args) => commands::selfcollision_study::run(&args),
        Command::Render(args) => commands::render::run(&args),
        Command::View(args) => viewer::run(args),
    };
    match result {
        Ok(()) => ExitCode::SUCCESS,
        Err(error) => {
            // The message chain is for users; a backtrace of our own code would only bury it.
            eprintln!("error: {error}");
            for cause in error.chain().skip(1) {
                eprintln!("  caused by: {cause}");
            }
            ExitCode::FAILURE
        }
    }
}
