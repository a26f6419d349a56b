//! `balls.wgsl`: dynamic balls (the rule of `hooke_core::collide::advance_balls`). `advance`
//! runs one workgroup per collider, sums the cloth's reactions on it in a fixed tree order
//! (deterministic, no atomics) and moves the ball; `contacts`, one invocation, lets each ball
//! meet the planes and the other balls. Recorded into the collide pass, after `collide`.

use super::collide::Collide;
use crate::context::{GpuContext, GpuError};
use crate::gpu::{Kernel, WORKGROUP_SIZE};
use crate::model::GpuModel;
use crate::state::GpuState;

#[derive(Debug)]
pub struct Balls {
    /// One workgroup per collider.
    advance: Kernel,
    /// One invocation.
    contacts: Kernel,
}

impl Balls {
    /// The ball passes, when the model has dynamic balls.
    pub fn new(
        context: &GpuContext,
        model: &GpuModel,
        state: &GpuState,
        collide: &Collide,
    ) -> Result<Option<Self>, GpuError> {
        if !hooke_core::collide::any_dynamic(&model.model.collision.colliders) {
            return Ok(None);
        }
        let colliders = model.model.collision.colliders.len() as u32;
        let advance = Kernel::new(
            context,
            "balls advance",
            super::BALLS,
            "advance",
            colliders * WORKGROUP_SIZE,
            |current| {
                vec![
                    (0, model.uniforms_binding(current)),
                    (1, collide.colliders.as_entire_binding()),
                    (2, collide.reactions.as_entire_binding()),
                    (4, state.status.as_entire_binding()),
                ]
            },
        )?;
        let contacts = Kernel::new(
            context,
            "balls contacts",
            super::BALLS,
            "contacts",
            1,
            |current| {
                vec![
                    (0, model.uniforms_binding(current)),
                    (1, collide.colliders.as_entire_binding()),
                    (3, state.status.as_entire_binding()),
                    (12, collide.keyframes.as_entire_binding()),
                ]
            },
        )?;
        Ok(Some(Self { advance, contacts }))
    }

    /// Records both kernels into an open pass (they see the collide kernel's writes).
    pub fn encode_in(&self, pass: &mut wgpu::ComputePass<'_>) {
        self.advance.encode_in(pass, 0);
        self.contacts.encode_in(pass, 0);
    }
}
