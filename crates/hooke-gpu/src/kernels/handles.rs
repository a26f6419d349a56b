//! `handles.wgsl`: pinned vertices moved by a path or a collider (the rule of
//! `hooke_core::handles`), placed after the colliders and balls of the step. One invocation
//! per handle vertex; a handle's keyframes follow the colliders' in its own copy of the
//! keyframe buffer, so `paths.wgsl` samples both.

use bytemuck::Zeroable;
use glam::Vec3;
use hooke_core::collide::MAX_KEYFRAMES;
use hooke_core::handles::HandleMotion;

use super::collide::{Collide, keyframe_entries};
use crate::context::{GpuContext, GpuError};
use crate::gpu::{Kernel, storage};
use crate::layout::GpuCollider;
use crate::model::GpuModel;
use crate::state::GpuState;

#[derive(Debug)]
pub struct Handles {
    pub kernel: Kernel,
    bytes: u64,
}

impl Handles {
    /// The handle pass, when the model has handles. `collide` holds the colliders they may
    /// follow (as balls move them).
    pub fn new(
        context: &GpuContext,
        model: &GpuModel,
        state: &GpuState,
        collide: Option<&Collide>,
    ) -> Result<Option<Self>, GpuError> {
        let cpu = &model.model;
        if cpu.handles.is_empty() {
            return Ok(None);
        }
        // Per handle vertex: its initial position, then (vertex, handle) as u32 bits.
        let mut entries: Vec<[[u32; 4]; 2]> = Vec::new();
        let mut records = Vec::new();
        let mut keyframes = keyframe_entries(&cpu.collision.colliders);
        for (h, handle) in cpu.handles.iter().enumerate() {
            for &v in &handle.vertices {
                let p = cpu.initial_positions[v as usize].as_vec3();
                let rest = [p.x.to_bits(), p.y.to_bits(), p.z.to_bits(), 0];
                entries.push([rest, [v, h as u32, 0, 0]]);
            }
            let mut slots = [[0.0f32; 4]; MAX_KEYFRAMES];
            let (motion, anchor) = match &handle.motion {
                HandleMotion::Path(path) => {
                    for (slot, (t, d)) in slots.iter_mut().zip(path.keyframes()) {
                        let d = d.as_vec3();
                        *slot = [*t as f32, d.x, d.y, d.z];
                    }
                    let repeat = if path.repeat { 1.0 } else { 0.0 };
                    (
                        [-1.0, 0.0, repeat, path.keyframes().len() as f32],
                        Vec3::ZERO,
                    )
                }
                &HandleMotion::Collider(c) => {
                    let start = cpu.collision.colliders[c].at(0.0).anchor().as_vec3();
                    ([c as f32, 0.0, 0.0, 0.0], start)
                }
            };
            records.push(motion);
            records.push([anchor.x, anchor.y, anchor.z, 0.0]);
            keyframes.extend(slots);
        }
        let none = wgpu::BufferUsages::empty();
        let vertices = storage(context, "handle vertices", &entries, none);
        let records_buffer = storage(context, "handles", &records, none);
        let keyframes_buffer = storage(context, "handle keyframes", &keyframes, none);
        let placeholder = storage(context, "no colliders", &[GpuCollider::zeroed()], none);
        let colliders = collide.map_or(&placeholder, |c| &c.colliders);
        let kernel = Kernel::new(
            context,
            "handles",
            super::HANDLES,
            "main",
            entries.len() as u32,
            |current| {
                vec![
                    (0, model.uniforms_binding(current)),
                    (1, state.positions[current].as_entire_binding()),
                    (2, state.positions[1 - current].as_entire_binding()),
                    (3, state.deltas.as_entire_binding()),
                    (4, vertices.as_entire_binding()),
                    (5, colliders.as_entire_binding()),
                    (6, state.status.as_entire_binding()),
                    (8, records_buffer.as_entire_binding()),
                    (12, keyframes_buffer.as_entire_binding()),
                ]
            },
        )?;
        let bytes = 16 * (2 * entries.len() + records.len() + keyframes.len()) as u64;
        Ok(Some(Self { kernel, bytes }))
    }

    /// Bytes held.
    pub fn bytes(&self) -> u64 {
        self.bytes
    }
}
