//! `collide.wgsl`: the cloth against spheres, planes and capsules (the rule of
//! `hooke_core::collide`). A vertex that ended inside a collider grown by the thickness moves
//! out along the normal, with friction on its motion relative to the collider. Scripted
//! colliders are placed by the step counter; with dynamic balls each vertex's reaction per
//! collider is written for `balls.wgsl`.
//!
//! The collider records ([`GpuCollider`]) live here: their shapes are the model's, and a
//! dynamic ball's place, velocity and spin are state that `balls.wgsl` moves.

use std::mem::{offset_of, size_of};

use hooke_core::collide::{Collider, MAX_KEYFRAMES, Shape};
use hooke_core::{BallPush, collide};

use super::balls::Balls;
use crate::context::{GpuContext, GpuError};
use crate::gpu::{self, Kernel, read_back, storage, zeroed};
use crate::layout::GpuCollider;
use crate::model::{GpuModel, vec4s};
use crate::state::GpuState;

#[derive(Debug)]
pub struct Collide {
    kernel: Kernel,
    /// One [`GpuCollider`] per collider.
    pub colliders: wgpu::Buffer,
    /// `MAX_KEYFRAMES` slots `(t, x, y, z)` per collider.
    pub keyframes: wgpu::Buffer,
    /// Per vertex and collider, the reaction on a dynamic ball (N).
    pub reactions: wgpu::Buffer,
    /// The colliders as the model gives them.
    settings: Vec<Collider>,
    bytes: u64,
}

impl Collide {
    /// The collision pass of the model's colliders; `None` when it has none.
    pub fn new(
        context: &GpuContext,
        model: &GpuModel,
        state: &GpuState,
    ) -> Result<Option<Self>, GpuError> {
        let settings = &model.model.collision.colliders;
        if settings.is_empty() {
            return Ok(None);
        }
        let records: Vec<GpuCollider> = settings.iter().map(record_of).collect();
        let copy = wgpu::BufferUsages::COPY_SRC | wgpu::BufferUsages::COPY_DST;
        let colliders = storage(context, "colliders", &records, copy);
        let keyframe_slots = keyframe_entries(settings);
        let keyframes = storage(
            context,
            "collider keyframes",
            &keyframe_slots,
            wgpu::BufferUsages::COPY_DST,
        );
        let n = model.model.vertex_count();
        let reaction_bytes = if collide::any_dynamic(settings) {
            vec4s(n * settings.len())
        } else {
            16
        };
        gpu::check_binding_size(context, "collider reactions", reaction_bytes)?;
        let reactions = zeroed(
            context,
            "collider reactions",
            reaction_bytes,
            wgpu::BufferUsages::empty(),
        );
        let kernel = Kernel::new(
            context,
            "collide",
            super::COLLIDE,
            "main",
            n as u32,
            |current| {
                vec![
                    (0, model.uniforms_binding(current)),
                    (1, state.positions[current].as_entire_binding()),
                    (2, state.positions[1 - current].as_entire_binding()),
                    (3, state.deltas.as_entire_binding()),
                    (4, model.scales.as_entire_binding()),
                    (5, colliders.as_entire_binding()),
                    (6, state.status.as_entire_binding()),
                    (7, reactions.as_entire_binding()),
                    (12, keyframes.as_entire_binding()),
                ]
            },
        )?;
        let bytes = (size_of::<GpuCollider>() * records.len()) as u64
            + (16 * keyframe_slots.len()) as u64
            + reaction_bytes;
        Ok(Some(Self {
            kernel,
            colliders,
            keyframes,
            reactions,
            settings: settings.clone(),
            bytes,
        }))
    }

    /// Bytes held.
    pub fn bytes(&self) -> u64 {
        self.bytes
    }

    /// Sets each dynamic ball's applied force to its setting's plus `pushes`: one 16-byte
    /// write per ball, nothing created.
    pub fn write_pushes(&self, context: &GpuContext, pushes: &[BallPush]) {
        let mut running = self.settings.clone();
        collide::apply_pushes(&mut running, &self.settings, pushes);
        for (k, collider) in running.iter().enumerate() {
            if collider.dynamics.is_some() {
                let script = record_of(collider).script;
                context.queue.write_buffer(
                    &self.colliders,
                    record_offset(k) + offset_of!(GpuCollider, script) as u64,
                    bytemuck::cast_slice(&script),
                );
            }
        }
    }

    /// Puts the dynamic balls where `saved` has them, moving as they moved there. Their applied
    /// force (the `script` slot) stays what the control set.
    pub fn restore_balls(&self, context: &GpuContext, saved: &[Collider]) {
        for (k, (setting, then)) in self.settings.iter().zip(saved).enumerate() {
            if setting.dynamics.is_some() {
                let record = record_of(then);
                context.queue.write_buffer(
                    &self.colliders,
                    record_offset(k) + offset_of!(GpuCollider, place) as u64,
                    bytemuck::cast_slice(&[record.place, record.surface, record.motion]),
                );
            }
        }
    }

    /// The colliders at time `t`: scripted ones placed by their settings, dynamic balls read
    /// back from the GPU (a blocking read, and only when there are balls).
    pub fn read(&self, context: &GpuContext, t: f64) -> Result<Vec<Collider>, GpuError> {
        let mut placed = collide::placed(&self.settings, t);
        if !collide::any_dynamic(&placed) {
            return Ok(placed);
        }
        let bytes = read_back(context, &[(&self.colliders, self.colliders.size())])?;
        let records: Vec<GpuCollider> = bytemuck::pod_collect_to_vec(&bytes[0]);
        for (collider, record) in placed.iter_mut().zip(&records) {
            if collider.dynamics.is_none() {
                continue;
            }
            if let Shape::Sphere { center, .. } = &mut collider.shape {
                *center = glam::Vec3::from_slice(&record.place[..3]).as_dvec3();
            }
            collider.velocity = glam::Vec3::from_slice(&record.motion[..3]).as_dvec3();
            collider.spin = glam::Vec3::from_slice(&record.surface[..3]).as_dvec3();
        }
        Ok(placed)
    }

    /// Records copies of the dynamic balls' current places (centre, radius) into `target`, one
    /// `vec4` per sphere in collider order: how a renderer draws balls without a read-back.
    pub fn copy_spheres(&self, encoder: &mut wgpu::CommandEncoder, target: &wgpu::Buffer) {
        let spheres = self
            .settings
            .iter()
            .enumerate()
            .filter(|(_, c)| matches!(c.shape, Shape::Sphere { .. }));
        for (slot, (k, collider)) in spheres.enumerate() {
            if collider.dynamics.is_some() {
                encoder.copy_buffer_to_buffer(
                    &self.colliders,
                    record_offset(k) + offset_of!(GpuCollider, place) as u64,
                    target,
                    (slot * 16) as u64,
                    16,
                );
            }
        }
    }

    /// One compute pass: the cloth out of the colliders, then (with dynamic balls) the balls
    /// moved by the cloth's reaction and their contacts.
    pub fn encode(
        &self,
        encoder: &mut wgpu::CommandEncoder,
        current: usize,
        balls: Option<&Balls>,
        timestamps: Option<wgpu::ComputePassTimestampWrites<'_>>,
    ) {
        let mut pass = encoder.begin_compute_pass(&wgpu::ComputePassDescriptor {
            label: Some("collide"),
            timestamp_writes: timestamps,
        });
        self.kernel.encode_in(&mut pass, current);
        if let Some(balls) = balls {
            balls.encode_in(&mut pass);
        }
    }
}

/// Byte offset of collider `k`'s record.
fn record_offset(k: usize) -> u64 {
    (k * size_of::<GpuCollider>()) as u64
}

/// The record collide.wgsl and balls.wgsl read for `collider` (see [`GpuCollider`]).
pub fn record_of(collider: &Collider) -> GpuCollider {
    let c = collider;
    let v = c.velocity.as_vec3();
    let capsule = if matches!(c.shape, Shape::Capsule { .. }) {
        1.0
    } else {
        0.0
    };
    let (inverse_mass, script) = match (c.dynamics, c.path) {
        (Some(d), _) => {
            let f = d.force.as_vec3();
            ((1.0 / d.mass) as f32, [f.x, f.y, f.z, d.restitution as f32])
        }
        (None, Some(path)) => {
            let repeat = if path.repeat { 1.0 } else { 0.0 };
            (0.0, [capsule, 0.0, repeat, path.keyframes().len() as f32])
        }
        (None, None) => (0.0, [capsule, 0.0, 0.0, 0.0]),
    };
    let friction = c.friction as f32;
    let (place, surface) = match c.shape {
        Shape::Sphere { center, radius } => {
            let (p, w) = (center.as_vec3(), c.spin.as_vec3());
            ([p.x, p.y, p.z, radius as f32], [w.x, w.y, w.z, friction])
        }
        Shape::Plane { point, normal } => {
            let (p, n) = (point.as_vec3(), normal.as_vec3());
            ([p.x, p.y, p.z, -1.0], [n.x, n.y, n.z, friction])
        }
        Shape::Capsule { start, end, radius } => {
            let (p, a) = (start.as_vec3(), (end - start).as_vec3());
            ([p.x, p.y, p.z, radius as f32], [a.x, a.y, a.z, friction])
        }
    };
    GpuCollider {
        place,
        surface,
        motion: [v.x, v.y, v.z, inverse_mass],
        script,
    }
}

/// `MAX_KEYFRAMES` slots `(t, x, y, z)` per collider for paths.wgsl.
pub(crate) fn keyframe_entries(colliders: &[Collider]) -> Vec<[f32; 4]> {
    colliders
        .iter()
        .flat_map(|c| {
            let mut slots = [[0.0f32; 4]; MAX_KEYFRAMES];
            if let Some(path) = c.path {
                for (slot, (t, p)) in slots.iter_mut().zip(path.keyframes()) {
                    let p = p.as_vec3();
                    *slot = [*t as f32, p.x, p.y, p.z];
                }
            }
            slots
        })
        .collect()
}

#[cfg(test)]
mod tests {
    use glam::DVec3;
    use hooke_core::Collision;
    use hooke_core::collide::{Collider, Shape, resolve};

    use super::*;
    use crate::kernels::testing::{as_gpu_sees, context, read_vec3s, run, stretched_scene};
    use crate::methods::GpuMethod;
    use crate::state::positions_to_vec4;

    /// float32 projections (a square root, a division, friction) against float64 from the same
    /// float32 positions: a few ulps of 1 m.
    const TOLERANCE_M: f64 = 1e-5;

    #[test]
    fn collide_moves_vertices_out_of_spheres_capsules_and_planes_as_hooke_core_does() {
        let Some(context) = context() else { return };
        let (mut scene, state) = stretched_scene();
        // The sheet lies in the x-z plane around the origin; it moves down 2 cm this step into
        // a sphere, a capsule and the ground, each with friction.
        scene.model.collision = Collision {
            colliders: vec![
                Collider::fixed(
                    Shape::Sphere {
                        center: DVec3::new(0.0, 0.05, 0.0),
                        radius: 0.3,
                    },
                    0.3,
                ),
                Collider::fixed(
                    Shape::Capsule {
                        start: DVec3::new(-0.5, 0.02, 0.3),
                        end: DVec3::new(0.5, 0.02, 0.3),
                        radius: 0.05,
                    },
                    0.5,
                ),
                Collider::fixed(
                    Shape::Plane {
                        point: DVec3::new(0.0, -0.002, 0.0),
                        normal: DVec3::Y,
                    },
                    0.6,
                ),
            ],
            thickness: 0.01,
            self_collision: None,
        };
        let n = scene.model.vertex_count();
        let model = GpuModel::new(&context, &scene.model, &scene.material, GpuMethod::Gather)
            .expect("model");
        model.write_uniforms(&context);
        let gpu_state = GpuState::new(&context, n);
        gpu_state.write(&context, &state);
        let current = gpu_state.current;
        let seen = as_gpu_sees(&state);
        let moved: Vec<DVec3> = seen
            .positions
            .iter()
            .map(|p| (*p + DVec3::new(0.0, -0.02, 0.0)).as_vec3().as_dvec3())
            .collect();
        context.queue.write_buffer(
            &gpu_state.positions[1 - current],
            0,
            bytemuck::cast_slice(&positions_to_vec4(&moved)),
        );
        let collide = Collide::new(&context, &model, &gpu_state)
            .expect("kernel")
            .expect("the model has colliders");
        run(&context, |e| collide.encode(e, current, None, None));
        let actual = read_vec3s(&context, &gpu_state.positions[1 - current], n);
        // The step ends at t = dt (the status counter starts at 0).
        let dt = scene.material.dt;
        let colliders = &scene.model.collision.colliders;
        let mut pushed = 0;
        for v in 0..n {
            let expected = if scene.model.pinned[v] {
                moved[v]
            } else {
                resolve(colliders, 0.01, dt, dt, seen.positions[v], moved[v])
            };
            pushed += usize::from(expected.distance(moved[v]) > 1e-4);
            assert!(
                actual[v].distance(expected) < TOLERANCE_M,
                "vertex {v}: {} vs {expected}",
                actual[v]
            );
        }
        assert!(
            pushed > n / 2,
            "only {pushed} of {n} vertices met a collider"
        );
    }
}
