//! hooke-gpu: the mass-spring step on the GPU with wgpu and WGSL (paper Section 4). The state
//! stays in GPU memory; reading it back is an explicit call.
//!
//! Layout: [`GpuModel`] and [`GpuState`] own the buffers; [`kernels`] holds one `<name>.rs`
//! beside each `<name>.wgsl`, owning that kernel's pipelines and bind groups; [`GpuSolver`] owns
//! the kernels and lists a step's passes once; [`render`] draws straight from the solver's
//! position buffer.

mod context;
pub mod gpu;
pub mod kernels;
pub mod layout;
mod methods;
mod model;
pub mod render;
mod solver;
mod state;
mod stencil;
mod step;

pub use context::{
    AdapterSummary, GpuContext, GpuError, OPTIONAL_FEATURES, gpu_required, list_adapters,
    test_context,
};
pub use kernels::radix_sort;
pub use methods::{Accumulation, GpuMemory, GpuMethod};
pub use model::GpuModel;
pub use solver::GpuSolver;
pub use state::{GpuState, positions_to_vec4};
pub use step::TIMED_STEPS_PER_SUBMISSION;

/// The wgpu this crate is built on, for callers that need its types.
pub use wgpu;
