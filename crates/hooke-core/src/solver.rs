//! What every solver (f64 reference, CPU, GPU) offers the rest of hooke.

use std::time::Duration;

use crate::collide::Collider;
use crate::selfcollide::{PartTimes, SelfCollision};
use crate::{Control, Material, State};

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
    /// The self-collision's parts, where a solver times them (the CPU's); within `collision`.
    pub self_collision: Option<PartTimes>,
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
    #[error("spring {spring} is listed as broken, but the model has {spring_count} springs")]
    NoSuchSpring { spring: u32, spring_count: usize },
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

/// Where per-phase times come from.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum TimingSource {
    /// GPU timestamp queries around each pass.
    Timestamps,
    /// Wall clock around each phase run (and, on a GPU, submitted) alone and waited for.
    WallClock,
}

/// Everything that changes while stepping: enough to continue a run exactly where it was.
#[derive(Clone, Debug, PartialEq)]
pub struct Snapshot {
    pub state: State,
    /// Every collider where it is now (dynamic balls with their velocity and spin).
    pub colliders: Vec<Collider>,
    pub steps_taken: u64,
    /// The springs torn so far, in order (see [`crate::tearing`]).
    pub broken_springs: Vec<u32>,
}

/// Advances a mass-spring system. A solver owns its state, wherever that lives (CPU or GPU
/// memory): stepping never moves it, and reading it back is an explicit call.
///
/// A solver is built from a [`crate::Model`] (fixed while stepping) and a [`Material`]; per-step
/// inputs arrive through [`Solver::set_control`]. Neither call rebuilds anything: a GPU solver
/// writes them into buffers it already has.
pub trait Solver: Send {
    /// A short description such as `"cpu scatter, 2 threads"`.
    fn describe(&self) -> String;

    /// Takes new integrator constants and stiffness scale, in place; they hold for every
    /// following step.
    fn set_material(&mut self, material: &Material) -> Result<(), SimError>;

    /// Takes new per-step inputs (drags, point forces, wind, pushes on balls), in place.
    fn set_control(&mut self, control: &Control) -> Result<(), SimError>;

    /// Turns self-collision on with `config`, or off. A change of set-up, not a per-step input:
    /// a GPU solver builds its self-collision pass here.
    fn set_self_collision(&mut self, config: Option<SelfCollision>) -> Result<(), SimError>;

    /// Advances `steps` time steps. Fails at the first step that produced a non-finite position.
    fn step(&mut self, steps: u32) -> Result<(), SimError>;

    /// One step with each phase timed (see [`PhaseTimes`]). Results equal [`Solver::step`]'s.
    fn step_timed(&mut self) -> Result<(PhaseTimes, TimingSource), SimError>;

    /// `steps` steps with each phase timed, a [`PhaseTimes`] a step. Results equal
    /// [`Solver::step`]'s. A solver that can time steps without stopping between them (the
    /// GPU: several to a submission) does; the others time them one at a time.
    fn steps_timed(&mut self, steps: u32) -> Result<(Vec<PhaseTimes>, TimingSource), SimError> {
        let mut times = Vec::with_capacity(steps as usize);
        let mut source = TimingSource::WallClock;
        for _ in 0..steps {
            let (step, from) = self.step_timed()?;
            times.push(step);
            source = from;
        }
        Ok((times, source))
    }

    /// Copies the current state out of the solver (a read-back for solvers whose state is remote).
    fn read_state(&self) -> Result<State, SimError>;

    /// Replaces the solver's state.
    fn write_state(&mut self, state: &State);

    /// Steps taken since the solver was built (or since the snapshot it was restored from).
    fn steps_taken(&self) -> u64;

    /// The colliders where they are now: scripted ones moved along their paths, dynamic balls
    /// where the simulation put them (a read-back for solvers whose state is remote).
    fn colliders(&self) -> Result<Vec<Collider>, SimError>;

    /// The springs torn so far, in order (a read-back for solvers whose state is remote).
    fn broken_springs(&self) -> Result<Vec<u32>, SimError>;

    /// The state, the colliders and the step counter, to continue from later.
    fn snapshot(&self) -> Result<Snapshot, SimError> {
        Ok(Snapshot {
            state: self.read_state()?,
            colliders: self.colliders()?,
            steps_taken: self.steps_taken(),
            broken_springs: self.broken_springs()?,
        })
    }

    /// Continues from `snapshot`: its state, its balls' places and motion, its step counter
    /// (which places scripted colliders), its torn springs.
    fn restore(&mut self, snapshot: &Snapshot) -> Result<(), SimError>;
}
