//! The [`Simulation`] facade: one type over every solver.

use std::sync::Arc;

use hooke_core::collide::Collider;
use hooke_core::reference::ReferenceSolver;
use hooke_core::scene::Scene;
use hooke_core::{Model, SimError, SimParams, Solver, State};
use hooke_cpu::{CpuError, CpuOptions, CpuSolver};
use hooke_gpu::{GpuContext, GpuError, GpuMethod, GpuSolver};

/// Which solver a [`Simulation`] runs.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum SolverChoice {
    /// float64, single-threaded: slow and exact, the oracle.
    Reference,
    /// float32, multithreaded, SIMD.
    Cpu(CpuOptions),
    /// float32 on the GPU, state resident in GPU buffers.
    Gpu(GpuMethod),
}

/// A simulation could not be built.
#[derive(Debug, thiserror::Error)]
pub enum EngineError {
    #[error("starting the cpu solver: {0}")]
    Cpu(#[from] CpuError),
    #[error("starting the gpu solver: {0}")]
    Gpu(#[from] GpuError),
}

/// A model and the solver that advances it.
pub struct Simulation {
    solver: Box<dyn Solver>,
}

impl std::fmt::Debug for Simulation {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str(&self.solver.describe())
    }
}

impl Simulation {
    /// A simulation of `model` under `params` on the chosen solver. A GPU solver uses `gpu`, or
    /// opens the default adapter when it is `None`.
    pub fn new(
        model: &Model,
        params: &SimParams,
        choice: SolverChoice,
        gpu: Option<Arc<GpuContext>>,
    ) -> Result<Self, EngineError> {
        let solver: Box<dyn Solver> = match choice {
            SolverChoice::Reference => Box::new(ReferenceSolver::new(model, params)),
            SolverChoice::Cpu(options) => Box::new(CpuSolver::new(model, params, options)?),
            SolverChoice::Gpu(method) => {
                let context = match gpu {
                    Some(context) => context,
                    None => GpuContext::new()?,
                };
                Box::new(GpuSolver::new(context, model, params, method)?)
            }
        };
        Ok(Self { solver })
    }

    /// A simulation of a built scene.
    pub fn from_scene(
        scene: &Scene,
        choice: SolverChoice,
        gpu: Option<Arc<GpuContext>>,
    ) -> Result<Self, EngineError> {
        Self::new(&scene.model, &scene.params, choice, gpu)
    }

    /// Advances `steps` time steps.
    pub fn step(&mut self, steps: u32) -> Result<(), SimError> {
        self.solver.step(steps)
    }

    /// The current state (a read-back on the GPU).
    pub fn state(&self) -> Result<State, SimError> {
        Ok(self.solver.read_state())
    }

    /// The colliders where they are now.
    pub fn colliders(&self) -> Result<Vec<Collider>, SimError> {
        Ok(self.solver.colliders())
    }
}
