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

/// Padded rows are used while they hold at most this many entries per true entry, in quarters
/// (a grid's rows, of 6 entries but at its border, hold 1.0; the irregular bench mesh's, of 13,
/// would hold 2.2).
const MOST_PADDED_QUARTERS: usize = 5;

/// How the incidence table is laid out.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum IncidenceLayout {
    /// Each vertex's entries from its offset: summed by `accumulate_incidence.wgsl` into a
    /// force per vertex, which `integrate` reads.
    Offsets,
    /// Every vertex's entries padded to this many: summed and integrated in one pass
    /// (`integrate_incidence.wgsl`).
    Rows(u32),
}

impl IncidenceLayout {
    /// Rows as wide as the largest valence where padding them costs little, else offsets.
    pub fn for_model(model: &Model) -> Self {
        let widest = Self::widest(model);
        let padded = widest * model.vertex_count();
        if widest > 0 && 4 * padded <= MOST_PADDED_QUARTERS * model.adjacency.springs.len() {
            Self::Rows(widest as u32)
        } else {
            Self::Offsets
        }
    }

    /// The largest valence of `model`: the width of rows that hold every vertex's entries.
    pub fn widest(model: &Model) -> usize {
        let adjacency = &model.adjacency;
        (0..model.vertex_count())
            .map(|v| adjacency.range(v).len())
            .max()
            .unwrap_or(0)
    }

    /// The table's entries in this layout: each vertex's from its offset in the model's
    /// adjacency, or rows of the same entries padded to the width. A padding entry names the
    /// zero force past the springs' (the force pass's buffer keeps one) as a far end: it adds
    /// -0.0, which leaves every sum's bits.
    pub fn entries(self, model: &Model) -> Vec<u32> {
        let adjacency = &model.adjacency;
        let row = |v: usize| {
            adjacency.range(v).map(move |k| {
                let spring = adjacency.springs[k];
                let far = model.spring_ends[spring as usize][1] as usize == v;
                spring | if far { B_END } else { 0 }
            })
        };
        let vertices = 0..model.vertex_count();
        match self {
            Self::Offsets => vertices.flat_map(row).collect(),
            Self::Rows(width) => {
                let padding = model.spring_count() as u32 | B_END;
                let padded = |v: usize| {
                    let pad = width as usize - adjacency.range(v).len();
                    row(v).chain(std::iter::repeat_n(padding, pad))
                };
                vertices.flat_map(padded).collect()
            }
        }
    }
}

#[derive(Debug)]
pub struct AccumulateIncidence {
    pub kernel: Kernel,
    bytes: u64,
}

impl AccumulateIncidence {
    /// The accumulation of `spring_forces` by offsets (see [`IncidenceLayout::Offsets`]).
    pub fn new(
        context: &GpuContext,
        model: &Model,
        buffers: &ScatterBuffers<'_>,
        spring_forces: &wgpu::Buffer,
    ) -> Result<Self, GpuError> {
        let entries = IncidenceLayout::Offsets.entries(model);
        let none = wgpu::BufferUsages::empty();
        let offsets = &model.adjacency.offsets;
        let offsets_buffer = storage(context, "incidence offsets", offsets, none);
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
            bytes: bytes_of(offsets) + bytes_of(&entries),
        })
    }

    /// Bytes of the incidence table (topology).
    pub fn bytes(&self) -> u64 {
        self.bytes
    }
}

#[cfg(test)]
mod tests {
    use hooke_core::scene::MeshSection;
    use hooke_testkit::benchmark_scene;

    use super::IncidenceLayout;
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

    #[test]
    fn rows_are_padded_only_where_that_costs_little() {
        let grid = benchmark_scene(MeshSection::unit_grid(12, 9), 108);
        assert_eq!(
            IncidenceLayout::for_model(&grid.model),
            IncidenceLayout::Rows(6)
        );
        let irregular = benchmark_scene(MeshSection::unit_irregular(2000, 5), 2000);
        assert_eq!(
            IncidenceLayout::for_model(&irregular.model),
            IncidenceLayout::Offsets
        );
    }
}
