//! [`GpuState`]: what changes every step, resident on the GPU. Positions are `vec4` per vertex
//! in two buffers with `STORAGE | VERTEX` usage that swap roles every step (a renderer binds the
//! current one); the deltas `d = x - x_prev` are updated in place.

use glam::DVec3;
use hooke_core::State;

use crate::context::{GpuContext, GpuError};
use crate::gpu::{read_back, storage, zeroed};
use crate::layout::GpuStatus;
use crate::model::vec4s;

#[derive(Debug)]
pub struct GpuState {
    pub positions: [wgpu::Buffer; 2],
    /// Which of `positions` holds `x(t)`; the other receives `x(t + dt)`.
    pub current: usize,
    pub deltas: wgpu::Buffer,
    /// First non-finite vertex and step, fixed-point overflow, the step clocks ([`GpuStatus`]).
    pub status: wgpu::Buffer,
    vertex_count: usize,
}

impl GpuState {
    pub fn new(context: &GpuContext, vertex_count: usize) -> Self {
        let copy = wgpu::BufferUsages::COPY_SRC | wgpu::BufferUsages::COPY_DST;
        Self {
            positions: [0, 1].map(|k| {
                zeroed(
                    context,
                    &format!("positions {k}"),
                    vec4s(vertex_count),
                    copy | wgpu::BufferUsages::VERTEX,
                )
            }),
            current: 0,
            deltas: zeroed(context, "deltas", vec4s(vertex_count), copy),
            status: storage(context, "status", &[GpuStatus::fresh(0)], copy),
            vertex_count,
        }
    }

    /// The buffer holding `x(t)`.
    pub fn current_positions(&self) -> &wgpu::Buffer {
        &self.positions[self.current]
    }

    /// After a step: the buffer that received `x(t + dt)` becomes current.
    pub fn advance(&mut self) {
        self.current = 1 - self.current;
    }

    /// Bytes of the positions and deltas.
    pub fn bytes(&self) -> u64 {
        3 * vec4s(self.vertex_count)
    }

    pub fn write(&self, context: &GpuContext, state: &State) {
        let positions = positions_to_vec4(&state.positions);
        let deltas: Vec<[f32; 4]> = state
            .positions
            .iter()
            .zip(&state.previous_positions)
            .map(|(p, q)| {
                let d = (*p - *q).as_vec3();
                [d.x, d.y, d.z, 0.0]
            })
            .collect();
        let queue = &context.queue;
        queue.write_buffer(
            self.current_positions(),
            0,
            bytemuck::cast_slice(&positions),
        );
        queue.write_buffer(&self.deltas, 0, bytemuck::cast_slice(&deltas));
    }

    /// Copies the state out (a blocking read-back).
    pub fn read(&self, context: &GpuContext) -> Result<State, GpuError> {
        let n = self.vertex_count;
        let bytes = read_back(
            context,
            &[
                (self.current_positions(), vec4s(n)),
                (&self.deltas, vec4s(n)),
            ],
        )?;
        let positions: Vec<[f32; 4]> = bytemuck::pod_collect_to_vec(&bytes[0]);
        let deltas: Vec<[f32; 4]> = bytemuck::pod_collect_to_vec(&bytes[1]);
        let as_dvec = |v: &[f32; 4]| DVec3::new(f64::from(v[0]), f64::from(v[1]), f64::from(v[2]));
        let positions: Vec<DVec3> = positions.iter().map(as_dvec).collect();
        let previous_positions = positions
            .iter()
            .zip(&deltas)
            .map(|(x, d)| *x - as_dvec(d))
            .collect();
        Ok(State {
            positions,
            previous_positions,
        })
    }

    /// Clears the status and sets the step counter (which places scripted colliders).
    pub fn reset_status(&self, context: &GpuContext, steps_taken: u64) {
        context.queue.write_buffer(
            &self.status,
            0,
            bytemuck::bytes_of(&GpuStatus::fresh(steps_taken as u32)),
        );
    }
}

/// Positions as the `vec4` per vertex (w = 1) that GPU position buffers hold.
pub fn positions_to_vec4(positions: &[DVec3]) -> Vec<[f32; 4]> {
    positions
        .iter()
        .map(|p| {
            let p = p.as_vec3();
            [p.x, p.y, p.z, 1.0]
        })
        .collect()
}
