//! Choosing a solver from command-line flags.

use anyhow::Context;
use clap::{Args, ValueEnum};
use hooke_core::reference::ReferenceSolver;
use hooke_core::{Model, SimParams, Solver};
use hooke_cpu::layout::VertexOrder;
use hooke_cpu::{CpuOptions, CpuSolver, Method};

#[derive(Clone, Copy, Debug, PartialEq, Eq, ValueEnum)]
pub enum Backend {
    /// float64, single-threaded: slow and exact, the oracle.
    Reference,
    /// float32, multithreaded, SIMD.
    Cpu,
}

#[derive(Clone, Copy, Debug, PartialEq, Eq, ValueEnum)]
pub enum MethodArg {
    /// Point-centric (PCA): every vertex sums its springs.
    Gather,
    /// Edge-centric (ECA): every spring once, then per-vertex accumulation.
    Scatter,
}

impl From<MethodArg> for Method {
    fn from(m: MethodArg) -> Self {
        match m {
            MethodArg::Gather => Method::Gather,
            MethodArg::Scatter => Method::Scatter,
        }
    }
}

#[derive(Clone, Copy, Debug, PartialEq, Eq, ValueEnum)]
pub enum OrderArg {
    /// The mesh's own vertex order.
    Mesh,
    /// Sorted by decreasing valence (the paper's texture layout).
    ValenceSorted,
}

impl From<OrderArg> for VertexOrder {
    fn from(o: OrderArg) -> Self {
        match o {
            OrderArg::Mesh => VertexOrder::Mesh,
            OrderArg::ValenceSorted => VertexOrder::ValenceSorted,
        }
    }
}

/// Flags shared by every command that builds a solver.
#[derive(Clone, Debug, Args)]
pub struct SolverArgs {
    /// Which solver runs the simulation.
    #[arg(long, value_enum, default_value_t = Backend::Cpu)]
    pub backend: Backend,
    /// Data structure of the cpu backend (gather is the faster one on CPUs we measured).
    #[arg(long, value_enum, default_value_t = MethodArg::Gather)]
    pub method: MethodArg,
    /// Worker threads of the cpu backend (default: one per core).
    #[arg(long)]
    pub threads: Option<usize>,
    /// Vertex order of the cpu backend.
    #[arg(long, value_enum, default_value_t = OrderArg::Mesh)]
    pub order: OrderArg,
}

impl SolverArgs {
    pub fn build(&self, model: &Model, params: &SimParams) -> anyhow::Result<Box<dyn Solver>> {
        Ok(match self.backend {
            Backend::Reference => Box::new(ReferenceSolver::new(model, params)),
            Backend::Cpu => {
                let options = CpuOptions {
                    method: self.method.into(),
                    threads: self.threads,
                    order: self.order.into(),
                    ..Default::default()
                };
                Box::new(CpuSolver::new(model, params, options).context("starting the cpu solver")?)
            }
        })
    }
}
