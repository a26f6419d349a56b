//! `tick.wgsl`: one invocation that advances the step counter in the status buffer, so
//! `integrate` can name a failing step and scripted colliders know the time.

use crate::context::{GpuContext, GpuError};
use crate::gpu::Kernel;
use crate::state::GpuState;

#[derive(Debug)]
pub struct Tick {
    pub kernel: Kernel,
}

impl Tick {
    pub fn new(context: &GpuContext, state: &GpuState) -> Result<Self, GpuError> {
        let kernel = Kernel::new(context, "tick", super::TICK, "main", 1, |_| {
            vec![(0, state.status.as_entire_binding())]
        })?;
        Ok(Self { kernel })
    }
}
