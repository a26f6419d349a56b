//! `force_springs.wgsl`: the edge-centric (ECA) force pass. One invocation per spring computes
//! its force (paper eq. 1) once, into a per-spring buffer that an accumulation then sums at
//! the vertices.

use crate::context::{GpuContext, GpuError};
use crate::gpu::{self, Kernel, zeroed};
use crate::model::{GpuModel, vec4s};
use crate::state::GpuState;

#[derive(Debug)]
pub struct ForceSprings {
    pub kernel: Kernel,
    /// One force per spring (scratch the accumulations read).
    pub spring_forces: wgpu::Buffer,
    spring_count: u32,
}

impl ForceSprings {
    pub fn new(context: &GpuContext, model: &GpuModel, state: &GpuState) -> Result<Self, GpuError> {
        let springs = model
            .springs()
            .ok_or_else(|| GpuError::Validation("spring forces need the spring records".into()))?;
        let spring_count = model.uniforms.spring_count;
        // Checked here, where it is allocated: gather and the atomic accumulations have none.
        // One zero force past the springs', never written, which padded incidence rows read.
        let size = vec4s(spring_count as usize + 1);
        gpu::check_binding_size(context, "spring forces", size)?;
        let spring_forces = zeroed(context, "spring forces", size, wgpu::BufferUsages::empty());
        let kernel = Kernel::new(
            context,
            "spring forces",
            super::FORCE_SPRINGS,
            "main",
            spring_count,
            |current| {
                vec![
                    (0, model.uniforms_binding(current)),
                    (1, state.positions[current].as_entire_binding()),
                    (2, springs.as_entire_binding()),
                    (3, spring_forces.as_entire_binding()),
                ]
            },
        )?;
        Ok(Self {
            kernel,
            spring_forces,
            spring_count,
        })
    }

    /// Bytes of the per-spring force buffer.
    pub fn bytes(&self) -> u64 {
        vec4s(self.spring_count as usize + 1)
    }
}
