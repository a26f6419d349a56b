//! hooke-gpu: the mass-spring step on the GPU with wgpu and WGSL (paper Section 4). The state
//! stays in GPU memory; reading it back is an explicit call.

mod context;
pub mod gpu;
mod kernels;
pub mod layout;
pub mod radix_sort;
pub mod render;
mod self_collide;
mod solver;

pub use context::{
    AdapterSummary, GpuContext, GpuError, OPTIONAL_FEATURES, gpu_required, list_adapters,
};
pub use solver::{Accumulation, GpuMemory, GpuMethod, GpuSolver, TimingSource, positions_to_vec4};

/// The wgpu this crate is built on, for callers that need its types.
pub use wgpu;
