//! Choosing a solver from command-line flags.

use anyhow::Context;
use clap::{Args, ValueEnum};
use hooke::{Simulation, SolverChoice};
use hooke_core::scene::Scene;
use hooke_cpu::layout::VertexOrder;
use hooke_cpu::{CpuOptions, Method};
use hooke_gpu::{Accumulation, GpuContext, GpuMethod};

#[derive(Clone, Copy, Debug, PartialEq, Eq, ValueEnum)]
pub enum Backend {
    /// float64, single-threaded: slow and exact, the oracle.
    Reference,
    /// float32, multithreaded, SIMD.
    Cpu,
    /// float32 on the GPU (wgpu; set WGPU_BACKEND / WGPU_ADAPTER_NAME to choose the adapter).
    Gpu,
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

/// How the GPU's scatter method sums spring forces at the vertices.
#[derive(Clone, Copy, Debug, PartialEq, Eq, ValueEnum)]
pub enum AccumulationArg {
    /// Float atomics (needs SHADER_FLOAT32_ATOMIC).
    AtomicF32,
    /// Fixed-point integer atomics (deterministic; overflow is reported).
    AtomicFixed,
    /// Each vertex gathers its springs' forces (deterministic, no atomics).
    Incidence,
    /// The paper's point primitives blended into a 32-bit float target (needs FLOAT32_BLENDABLE).
    BlendR32f,
    /// ... into a 16-bit float target.
    BlendR16f,
    /// ... into 8-bit fixed-point targets, as the paper had to.
    BlendRgba8,
}

impl From<AccumulationArg> for Accumulation {
    fn from(a: AccumulationArg) -> Self {
        match a {
            AccumulationArg::AtomicF32 => Accumulation::AtomicF32,
            AccumulationArg::AtomicFixed => Accumulation::AtomicFixed,
            AccumulationArg::Incidence => Accumulation::Incidence,
            AccumulationArg::BlendR32f => Accumulation::BlendR32f,
            AccumulationArg::BlendR16f => Accumulation::BlendR16f,
            AccumulationArg::BlendRgba8 => Accumulation::BlendRgba8,
        }
    }
}

#[derive(Clone, Copy, Debug, PartialEq, Eq, ValueEnum)]
pub enum OrderArg {
    /// The mesh's order, unless its neighbours lie far apart in it: then spatial.
    Auto,
    /// The mesh's own vertex order.
    Mesh,
    /// In rows through space, as a grid is numbered (for meshes numbered without care for
    /// locality).
    Spatial,
    /// Sorted by decreasing valence (the paper's texture layout).
    ValenceSorted,
}

impl From<OrderArg> for VertexOrder {
    fn from(o: OrderArg) -> Self {
        match o {
            OrderArg::Auto => VertexOrder::Auto,
            OrderArg::Mesh => VertexOrder::Mesh,
            OrderArg::Spatial => VertexOrder::Spatial,
            OrderArg::ValenceSorted => VertexOrder::ValenceSorted,
        }
    }
}

/// Flags shared by every command that builds a solver.
#[derive(Clone, Debug, Args)]
pub struct SolverArgs {
    /// Which solver runs the simulation (default: cpu for `run`, gpu for `view`, which then
    /// draws straight from the solver's buffers).
    #[arg(long, value_enum)]
    pub backend: Option<Backend>,
    /// Data structure (default: gather on the cpu, where it is faster; scatter on the gpu).
    #[arg(long, value_enum)]
    pub method: Option<MethodArg>,
    /// How gpu scatter accumulates forces.
    #[arg(long, value_enum, default_value_t = AccumulationArg::Incidence)]
    pub accumulation: AccumulationArg,
    /// Worker threads of the cpu backend (default: one per core).
    #[arg(long)]
    pub threads: Option<usize>,
    /// Vertex order of the cpu backend.
    #[arg(long, value_enum, default_value_t = OrderArg::Auto)]
    pub order: OrderArg,
}

impl SolverArgs {
    /// The solver the flags ask for; `default` is the backend when `--backend` is not given.
    pub fn choice(&self, default: Backend) -> SolverChoice {
        match self.backend.unwrap_or(default) {
            Backend::Reference => SolverChoice::Reference,
            Backend::Cpu => SolverChoice::Cpu(CpuOptions {
                method: self.method.unwrap_or(MethodArg::Gather).into(),
                threads: self.threads,
                order: self.order.into(),
                ..Default::default()
            }),
            Backend::Gpu => SolverChoice::Gpu(match self.method.unwrap_or(MethodArg::Scatter) {
                MethodArg::Gather => GpuMethod::Gather,
                MethodArg::Scatter => GpuMethod::Scatter(self.accumulation.into()),
            }),
        }
    }

    /// A simulation of `scene` on the solver the flags ask for (cpu unless `--backend`).
    pub fn build(&self, scene: &Scene) -> anyhow::Result<Simulation> {
        let choice = self.choice(Backend::Cpu);
        let gpu = match choice {
            SolverChoice::Gpu(_) => Some(open_gpu()?),
            _ => None,
        };
        Simulation::from_scene(scene, choice, gpu)
            .with_context(|| format!("starting the {} solver", choice.name()))
    }
}

/// Opens the GPU and says which adapter it is and which optional paths it lacks.
pub fn open_gpu() -> anyhow::Result<std::sync::Arc<GpuContext>> {
    let context = GpuContext::new().context("opening the GPU")?;
    eprintln!("gpu: {}", context.describe());
    for line in context
        .feature_report()
        .iter()
        .filter(|l| l.contains(": no"))
    {
        eprintln!("gpu: {line}");
    }
    Ok(context)
}
