//! hooke-core: the mass-spring model of Georgii & Westermann, "Mass-Spring Systems on the GPU",
//! its scenes and meshes, and the float64 reference solver every other solver is checked against.

pub mod atomic_file;
pub mod collide;
mod control;
pub mod diagnostics;
pub mod forces;
pub mod frames;
pub mod handles;
pub mod input_file;
mod material;
pub mod mesh;
mod model;
pub mod reference;
pub mod scene;
pub mod selfcollide;
mod solver;
pub mod stability;
mod state;
pub mod tearing;

pub use control::{BallPush, Control, Drag, PointForce, Wind};
pub use material::Material;
pub use model::{Adjacency, Collision, MassModel, Model, ModelError, ModelOptions, StiffnessModel};
pub use solver::{PhaseTimes, SimError, Snapshot, Solver, TimingSource};
pub use state::State;
