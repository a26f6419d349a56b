//! `accumulate_incidence.wgsl`: scatter's accumulation without atomics. Each vertex gathers its
//! springs' forces from the per-spring buffer in a fixed order (the far end's negated), so the
//! result is deterministic.

use hooke_core::Model;

use super::ScatterBuffers;
use crate::context::{GpuContext, GpuError};
use crate::gpu::{Kernel, storage};
use crate::model::bytes_of;

/// Set on an incidence entry when the vertex is the spring's far end (`B_END` in WGSL).
const B_END: u32 = 0x8000_0000;

#[derive(Debug)]
pub struct AccumulateIncidence {
    pub kernel: Kernel,
    bytes: u64,
}

impl AccumulateIncidence {
    pub fn new(
        context: &GpuContext,
        model: &Model,
        buffers: &ScatterBuffers<'_>,
        spring_forces: &wgpu::Buffer,
    ) -> Result<Self, GpuError> {
        let adjacency = &model.adjacency;
        let offsets: Vec<u32> = adjacency.offsets.clone();
        let entries: Vec<u32> = (0..model.vertex_count())
            .flat_map(|v| {
                adjacency.range(v).map(move |k| {
                    let spring = adjacency.springs[k];
                    let far = model.spring_ends[spring as usize][1] as usize == v;
                    spring | if far { B_END } else { 0 }
                })
            })
            .collect();
        let none = wgpu::BufferUsages::empty();
        let offsets_buffer = storage(context, "incidence offsets", &offsets, none);
        let entries_buffer = storage(context, "incidence entries", &entries, none);
        let kernel = Kernel::new(
            context,
            "accumulate incidence",
            super::ACCUMULATE_INCIDENCE,
            "main",
            buffers.vertex_count,
            |current| {
                vec![
                    (0, buffers.model.uniforms_binding(current)),
                    (1, spring_forces.as_entire_binding()),
                    (2, offsets_buffer.as_entire_binding()),
                    (3, entries_buffer.as_entire_binding()),
                    (4, buffers.forces.as_entire_binding()),
                ]
            },
        )?;
        Ok(Self {
            kernel,
            bytes: bytes_of(&offsets) + bytes_of(&entries),
        })
    }

    /// Bytes of the incidence table (topology).
    pub fn bytes(&self) -> u64 {
        self.bytes
    }
}

#[cfg(test)]
mod tests {
    use crate::kernels::testing::{accumulated, assert_close, stretched_scene};
    use crate::methods::Accumulation;

    /// float32 spring forces summed at the vertices, against float64 from the same float32
    /// positions: a few ulps of the largest force.
    const TOLERANCE: f64 = 1e-5;

    #[test]
    fn incidence_sums_spring_forces_at_the_vertices_as_the_reference_does() {
        if let Some(sums) = accumulated(Accumulation::Incidence, stretched_scene(), false) {
            assert_close(&sums.actual, &sums.expected, TOLERANCE, "incidence");
        }
    }
}
