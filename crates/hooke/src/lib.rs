//! hooke: the engine API that the CLI, the viewer, the Python package and the browser page drive.
//!
//! One [`Simulation`] holds a model and one of the solvers (the float64 reference, the CPU
//! solver or the GPU solver) behind the same calls.

mod simulation;

pub use simulation::{EngineError, Simulation, SolverChoice};
