//! hooke: the engine API that the CLI, the viewer, the Python package and the browser page
//! drive.
//!
//! A [`Simulation`] holds a model (fixed while stepping, colliders and self-collision set-up
//! included) and one of the solvers (the float64 reference, the CPU solver or the GPU solver)
//! behind the same calls: build from a scene or from arrays, `step`, read the state, drive it
//! live with a [`Control`] and a [`Material`] that are written in place, snapshot and restore,
//! time phases, report memory, and draw ([`OffscreenRun`], or a window's own renderer reading
//! [`Simulation::positions_buffer`]).
//!
//! ```
//! # fn main() -> Result<(), Box<dyn std::error::Error>> {
//! use hooke::{Arrays, Control, Material, Simulation, SolverChoice, model_from_arrays};
//! use hooke_core::{Drag, MassModel, StiffnessModel};
//! use hooke_cpu::CpuOptions;
//!
//! // Two triangles, the first two vertices pinned.
//! let vertices = [[0.0, 1.0, 0.0], [1.0, 1.0, 0.0], [0.0, 0.0, 0.0], [1.0, 0.0, 0.0]];
//! let model = model_from_arrays(&Arrays {
//!     vertices: &vertices,
//!     triangles: &[[0, 2, 1], [1, 2, 3]],
//!     pins: &[0, 1],
//!     stiffness: StiffnessModel::Uniform(100.0),
//!     mass: MassModel::TotalUniform(0.1),
//! })?;
//! let material = Material { dt: 1e-3, damping: 0.01, ..Default::default() };
//! let mut sim = Simulation::new(&model, &material, SolverChoice::Cpu(CpuOptions::default()), None)?;
//! sim.step(100)?;
//! // Pull vertex 3 toward a point, live: written into the solver, nothing rebuilt.
//! sim.set_control(Control {
//!     drags: vec![Drag { vertices: vec![3], target: [1.5, -0.5, 0.0].into(), stiffness: 20.0 }],
//!     ..Default::default()
//! })?;
//! sim.set_material(Material { stiffness_scale: 2.0, ..material })?;
//! sim.step(100)?;
//! let state = sim.state()?; // positions and previous positions, float64
//! # Ok(())
//! # }
//! ```

pub mod live;
pub mod live_view;
mod offscreen;
pub mod pointer;
mod simulation;
pub mod state_file;

pub use hooke_core::{Control, Material, Snapshot};
pub use offscreen::{FrameError, OffscreenRun};
pub use simulation::{
    Arrays, EngineError, MemoryReport, Simulation, SolverChoice, model_from_arrays,
};
