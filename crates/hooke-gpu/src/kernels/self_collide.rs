//! `self_collide.wgsl` (with `radix_sort.wgsl`): approximate self-collision, per staggered grid:
//! cell keys (after applying the previous grid's corrections, and counting the sort's first
//! digits), a radix sort and window corrections; then the last grid's corrections are applied.
//! All recorded into one compute pass after the collider pass. Same rule as
//! `hooke_core::selfcollide`.

use hooke_core::selfcollide::{self, SelfCollision};

use super::radix_sort::{RadixSort, SortGroup};
use crate::GpuError;
use crate::context::GpuContext;
use crate::gpu::{
    bind_group, compute_pipeline, compute_pipeline_with, dispatch_groups_in, dispatch_in, storage,
    uniform, zeroed,
};
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
    /// Per grid, by current position buffer (both read the grid's cells).
    key_groups: Vec<[wgpu::BindGroup; 2]>,
    correct_groups: Vec<[wgpu::BindGroup; 2]>,
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
        let group = SortGroup::for_adapter(&context.info);
        Self::with_sort_group(context, gpu_model, state, config, group)
    }

    /// [`SelfCollidePass::new`] with the sort's workgroups of a given size (tests run both).
    fn with_sort_group(
        context: &GpuContext,
        gpu_model: &GpuModel,
        state: &GpuState,
        config: &SelfCollision,
        group: SortGroup,
    ) -> Result<Self, GpuError> {
        let model = &gpu_model.model;
        let n = model.vertex_count() as u32;
        let key_bits = selfcollide::key_bits(model.vertex_count());
        // `cell_keys` counts the first digits, in workgroups of the sort's size.
        let sort = RadixSort::new(context, n, key_bits, true, group)?;
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
                        apply_previous: u32::from(k > 0),
                        block_count: sort.block_count(),
                    },
                )
            })
            .collect();
        let cell_keys = compute_pipeline_with(
            context,
            "cell keys",
            super::SELF_COLLIDE,
            "cell_keys",
            &group.constants(),
        )?;
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
        // A bind group per grid (its uniforms) and per current position buffer.
        let per_grid = |make: &dyn Fn(&wgpu::Buffer, usize) -> wgpu::BindGroup| {
            uniforms
                .iter()
                .map(|u| [0, 1].map(|current| make(u, current)))
                .collect::<Vec<_>>()
        };
        let key_groups = per_grid(&|u, current| {
            bind_group(
                context,
                "cell keys",
                &cell_keys.get_bind_group_layout(0),
                &[
                    (0, u.as_entire_binding()),
                    (2, sort.pairs().as_entire_binding()),
                    (7, corrections.as_entire_binding()),
                    (8, target(current).as_entire_binding()),
                    (9, state.deltas.as_entire_binding()),
                    (10, sort.histogram().as_entire_binding()),
                ],
            )
        });
        let correct_groups = per_grid(&|u, current| {
            bind_group(
                context,
                "self-collision correct",
                &correct.get_bind_group_layout(0),
                &[
                    (0, u.as_entire_binding()),
                    (1, target(current).as_entire_binding()),
                    (2, sort.sorted_pairs().as_entire_binding()),
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

    /// Dispatches per step: per grid, the keys (which apply the previous grid's corrections
    /// and count the sort's first digits), the rest of the sort and the corrections; then the
    /// last grid's application.
    pub fn dispatches(&self) -> u32 {
        self.key_groups.len() as u32 * (2 + self.sort.dispatches()) + 1
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
        // One workgroup per sort block.
        let blocks = self.sort.block_count();
        for (keys, correct) in self.key_groups.iter().zip(&self.correct_groups) {
            dispatch_groups_in(&mut pass, &self.cell_keys, &keys[current], blocks);
            self.sort.encode(&mut pass);
            dispatch_in(&mut pass, &self.correct, &correct[current], n);
        }
        dispatch_in(&mut pass, &self.apply, &self.apply_groups[current], n);
    }
}

#[cfg(test)]
mod tests {
    use glam::{DVec3, Vec3};
    use hooke_core::State;
    use hooke_core::diagnostics::relative_l2;

    use super::*;
    use std::path::Path;

    use hooke_core::scene::{MeshSection, Scene, SceneFile};

    use crate::kernels::testing::{context, read_vec3s, run};
    use crate::methods::GpuMethod;

    /// The same float32 pushes in the same sorted order; the push weights are `dt^2/m` here and
    /// `1/m` there, whose ratios round differently in the last bit.
    const TOLERANCE: f64 = 1e-6;

    #[test]
    fn self_collision_pass_parts_close_pairs_as_hooke_core_does() {
        let Some(context) = context() else { return };
        // One to three sort passes (8, 16 and 24 key bits), one to 33 sort blocks, with the
        // sort's workgroups of either size whatever the adapter would get.
        for vertices in [100, 144, 3000, 33_000] {
            let scene = SceneFile::benchmark(MeshSection::unit_irregular(vertices, 4), vertices)
                .build(Path::new("kernel test"), true)
                .expect("scene");
            for group in SortGroup::ALL {
                check_folded_sheet(&context, &scene, group);
            }
        }
    }

    fn check_folded_sheet(context: &GpuContext, scene: &Scene, group: SortGroup) {
        let config = SelfCollision::for_model(&scene.model);
        // The sheet folded along x = 0: its x > 0 half lies a quarter of the distance above the
        // other, so many unjoined pairs are too close.
        let folded: Vec<DVec3> = scene
            .model
            .initial_positions
            .iter()
            .map(|p| {
                if p.x > 0.0 {
                    DVec3::new(-p.x, p.y + 0.25 * config.distance, p.z)
                } else {
                    *p
                }
            })
            .map(|p| p.as_vec3().as_dvec3())
            .collect();
        let n = folded.len();
        let model = GpuModel::new(context, &scene.model, &scene.material, GpuMethod::Gather)
            .expect("model");
        model.write_uniforms(context);
        let mut gpu_state = GpuState::new(context, n);
        // The pass works on the buffer a step writes: put the folded sheet in both.
        let at_rest = State::at_rest(folded.clone());
        gpu_state.write(context, &at_rest);
        gpu_state.advance();
        gpu_state.write(context, &at_rest);
        gpu_state.advance();
        let pass = SelfCollidePass::with_sort_group(context, &model, &gpu_state, &config, group)
            .expect("pass");
        run(context, |e| pass.encode(e, gpu_state.current, None));
        let actual = read_vec3s(context, &gpu_state.positions[1 - gpu_state.current], n);
        let mut expected: Vec<Vec3> = folded.iter().map(|p| p.as_vec3()).collect();
        let weights = selfcollide::inverse_masses(&scene.model);
        selfcollide::resolve(&mut expected, &weights, &scene.model.adjacency, &config);
        let expected: Vec<DVec3> = expected.iter().map(|p| p.as_dvec3()).collect();
        let pushed = expected
            .iter()
            .zip(&folded)
            .filter(|(a, b)| a.distance(**b) > 1e-5)
            .count();
        assert!(pushed > n / 20, "{n} vertices: only {pushed} pushed apart");
        let error = relative_l2(&actual, &expected);
        assert!(
            error < TOLERANCE,
            "{n} vertices, {group:?}: relative L2 {error:.2e}"
        );
    }
}
