//! What every solver (f64 reference, CPU, later GPU) offers the rest of hooke.

use std::time::Duration;

use crate::collide::Collider;
use crate::{SimParams, State};

/// Time of each phase of one step, as the paper's Table 2 splits it.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct PhaseTimes {
    /// Point forces, drags and wind (zero when there are none).
    pub external: Duration,
    pub force_calculation: Duration,
    /// Scatter only: summing each vertex's spring forces.
    pub force_accumulation: Option<Duration>,
    pub integration: Duration,
    /// Colliders and self-collision (zero when there are none).
    pub collision: Duration,
}

impl PhaseTimes {
    pub fn total(&self) -> Duration {
        self.external
            + self.force_calculation
            + self.force_accumulation.unwrap_or_default()
            + self.integration
            + self.collision
    }
}

/// The simulation left the range where its numbers mean anything.
#[derive(Debug, thiserror::Error, PartialEq)]
pub enum SimError {
    #[error(
        "step {step}: vertex {vertex} reached a non-finite position; the time step is too large for the stiffness, or a force is NaN"
    )]
    NonFinite { step: u64, vertex: usize },
    #[error(
        "step {step}: the simulation exploded: spring {spring} (vertices {a}-{b}) is stretched to {stretch:.1e} times its rest length"
    )]
    Exploded {
        step: u64,
        spring: usize,
        a: u32,
        b: u32,
        stretch: f64,
    },
    #[error(
        "step {step}: the dynamic ball of collider {collider} reached a non-finite position or velocity; its mass is too small for the forces on it, or the time step too large"
    )]
    BallNonFinite { step: u64, collider: usize },
    #[error("step {step}: {detail}")]
    Overflow { step: u64, detail: String },
    #[error("the solver's device failed: {0}")]
    Device(String),
}

/// Advances a mass-spring system. A solver owns its state, wherever that lives (CPU or GPU
/// memory): stepping never moves it, and reading it back is an explicit call.
pub trait Solver: Send {
    /// A short description such as `"cpu scatter, 2 threads"`.
    fn describe(&self) -> String;

    /// Takes new parameters; they hold for every following step.
    fn set_params(&mut self, params: &SimParams);

    /// Advances `steps` time steps. Fails at the first step that produced a non-finite position.
    fn step(&mut self, steps: u32) -> Result<(), SimError>;

    /// Copies the current state out of the solver (a read-back for solvers whose state is remote).
    fn read_state(&self) -> State;

    /// Replaces the solver's state.
    fn write_state(&mut self, state: &State);

    /// Steps taken since the solver was built.
    fn steps_taken(&self) -> u64;

    /// The colliders where they are now: scripted ones moved along their paths, dynamic balls
    /// where the simulation put them (a read-back for solvers whose state is remote).
    fn colliders(&self) -> Vec<Collider>;
}
