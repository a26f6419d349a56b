//! `self_collide.wgsl` (with `radix_sort.wgsl`): approximate self-collision, per staggered grid:
//! cell keys, a radix sort, window corrections and their application, all recorded into one
//! compute pass after the collider pass. Same rule as `hooke_core::selfcollide`.

use hooke_core::selfcollide::{self, SelfCollision};

use super::radix_sort::RadixSort;
use crate::GpuError;
use crate::context::GpuContext;
use crate::gpu::{bind_group, compute_pipeline, dispatch_in, storage, uniform, zeroed};
use crate::layout::SelfUniforms;
use crate::model::GpuModel;
use crate::state::GpuState;

#[derive(Debug)]
pub struct SelfCollidePass {
    vertex_count: u32,
    sort: RadixSort,
    cell_keys: wgpu::ComputePipeline,
    correct: wgpu::ComputePipeline,
    apply: wgpu::ComputePipeline,
    /// Per grid, by current position buffer.
    key_groups: Vec<[wgpu::BindGroup; 2]>,
    correct_groups: [wgpu::BindGroup; 2],
    apply_groups: [wgpu::BindGroup; 2],
    bytes: u64,
}

impl SelfCollidePass {
    /// The pass works on the position buffer that receives the step's result; a pair's push is
    /// weighted by the model's `dt^2 / m` per vertex (zero for pinned ones).
    pub fn new(
        context: &GpuContext,
        gpu_model: &GpuModel,
        state: &GpuState,
        config: &SelfCollision,
    ) -> Result<Self, GpuError> {
        let model = &gpu_model.model;
        let n = model.vertex_count() as u32;
        let key_bits = selfcollide::key_bits(model.vertex_count());
        let sort = RadixSort::new(context, n, key_bits)?;
        let offsets = storage(
            context,
            "self-collision adjacency offsets",
            &model.adjacency.offsets,
            wgpu::BufferUsages::empty(),
        );
        let neighbors = storage(
            context,
            "self-collision adjacency",
            &model.adjacency.neighbors,
            wgpu::BufferUsages::empty(),
        );
        let corrections = zeroed(
            context,
            "self-collision corrections",
            16 * u64::from(n),
            wgpu::BufferUsages::empty(),
        );
        let uniforms: Vec<wgpu::Buffer> = (0..config.grids)
            .map(|k| {
                uniform(
                    context,
                    &SelfUniforms {
                        vertex_count: n,
                        window: config.window,
                        distance: config.distance as f32,
                        inverse_cell: (1.0 / config.cell_size) as f32,
                        offset: config.grid_offset(k),
                        key_bits,
                        pad: [0; 2],
                    },
                )
            })
            .collect();
        let cell_keys = compute_pipeline(context, "cell keys", super::SELF_COLLIDE, "cell_keys")?;
        let correct = compute_pipeline(
            context,
            "self-collision correct",
            super::SELF_COLLIDE,
            "correct",
        )?;
        let apply = compute_pipeline(
            context,
            "self-collision apply",
            super::SELF_COLLIDE,
            "apply",
        )?;
        // The pass works on the buffer the step writes: positions[1 - current].
        let target = |current: usize| &state.positions[1 - current];
        let key_groups = uniforms
            .iter()
            .map(|u| {
                [0, 1].map(|current| {
                    bind_group(
                        context,
                        "cell keys",
                        &cell_keys.get_bind_group_layout(0),
                        &[
                            (0, u.as_entire_binding()),
                            (1, target(current).as_entire_binding()),
                            (2, sort.keys().as_entire_binding()),
                            (3, sort.values().as_entire_binding()),
                        ],
                    )
                })
            })
            .collect();
        let correct_groups = [0, 1].map(|current| {
            bind_group(
                context,
                "self-collision correct",
                &correct.get_bind_group_layout(0),
                &[
                    (0, uniforms[0].as_entire_binding()),
                    (1, target(current).as_entire_binding()),
                    (2, sort.keys().as_entire_binding()),
                    (3, sort.values().as_entire_binding()),
                    (4, gpu_model.scales.as_entire_binding()),
                    (5, offsets.as_entire_binding()),
                    (6, neighbors.as_entire_binding()),
                    (7, corrections.as_entire_binding()),
                ],
            )
        });
        let apply_groups = [0, 1].map(|current| {
            bind_group(
                context,
                "self-collision apply",
                &apply.get_bind_group_layout(0),
                &[
                    (0, uniforms[0].as_entire_binding()),
                    (7, corrections.as_entire_binding()),
                    (8, target(current).as_entire_binding()),
                    (9, state.deltas.as_entire_binding()),
                ],
            )
        });
        let bytes = sort.bytes()
            + 4 * (model.adjacency.offsets.len() + model.adjacency.neighbors.len()) as u64
            + 16 * u64::from(n);
        Ok(Self {
            vertex_count: n,
            sort,
            cell_keys,
            correct,
            apply,
            key_groups,
            correct_groups,
            apply_groups,
            bytes,
        })
    }

    /// GPU memory held, bytes.
    pub fn bytes(&self) -> u64 {
        self.bytes
    }

    /// Records every grid's passes for a step whose current position buffer is `current`.
    pub fn encode(
        &self,
        encoder: &mut wgpu::CommandEncoder,
        current: usize,
        timestamp_writes: Option<wgpu::ComputePassTimestampWrites<'_>>,
    ) {
        let mut pass = encoder.begin_compute_pass(&wgpu::ComputePassDescriptor {
            label: Some("self-collision"),
            timestamp_writes,
        });
        let n = self.vertex_count;
        for groups in &self.key_groups {
            dispatch_in(&mut pass, &self.cell_keys, &groups[current], n);
            self.sort.encode(&mut pass);
            dispatch_in(&mut pass, &self.correct, &self.correct_groups[current], n);
            dispatch_in(&mut pass, &self.apply, &self.apply_groups[current], n);
        }
    }
}
