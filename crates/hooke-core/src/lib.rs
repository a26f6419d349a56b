//! hooke-core: the mass-spring model of Georgii & Westermann, "Mass-Spring Systems on the GPU",
//! its scenes and meshes, and the float64 reference solver every other solver is checked against.

pub mod atomic_file;
pub mod collide;
pub mod diagnostics;
pub mod forces;
pub mod mesh;
mod model;
mod params;
pub mod reference;
pub mod scene;
pub mod selfcollide;
mod solver;
pub mod stability;
mod state;
#[doc(hidden)]
pub mod test_scenes;

pub use model::{Adjacency, MassModel, Model, ModelError, ModelOptions, StiffnessModel};
pub use params::{Drag, PointForce, SimParams, Wind};
pub use solver::{PhaseTimes, SimError, Solver};
pub use state::State;
