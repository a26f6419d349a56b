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

#[derive(Debug)]
pub struct AccumulateIncidence {
    pub kernel: Kernel,
    bytes: u64,
}

/// How the incidence table is laid out for the kernel.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum IncidenceLayout {
    /// Each vertex's entries from its offset (`main`).
    Offsets,
    /// Every vertex's entries padded to the same count (`rows`).
    Rows(u32),
}

impl IncidenceLayout {
    /// Rows as wide as the largest valence where padding them costs little, else offsets.
    pub fn for_model(model: &Model) -> Self {
        let adjacency = &model.adjacency;
        let n = model.vertex_count();
        let widest = (0..n).map(|v| adjacency.range(v).len()).max().unwrap_or(0);
        let entries = adjacency.springs.len();
        if widest > 0 && 4 * widest * n <= MOST_PADDED_QUARTERS * entries {
            Self::Rows(widest as u32)
        } else {
            Self::Offsets
        }
    }
}

impl AccumulateIncidence {
    /// The accumulation over `spring_forces`, which must hold one zero force past the springs'.
    pub fn new(
        context: &GpuContext,
        model: &Model,
        buffers: &ScatterBuffers<'_>,
        spring_forces: &wgpu::Buffer,
    ) -> Result<Self, GpuError> {
        let layout = IncidenceLayout::for_model(model);
        Self::with_layout(context, model, buffers, spring_forces, layout)
    }

    /// [`AccumulateIncidence::new`] with the table laid out as `layout`.
    pub fn with_layout(
        context: &GpuContext,
        model: &Model,
        buffers: &ScatterBuffers<'_>,
        spring_forces: &wgpu::Buffer,
        layout: IncidenceLayout,
    ) -> Result<Self, GpuError> {
        let adjacency = &model.adjacency;
        let entry = |v: usize, k: usize| {
            let spring = adjacency.springs[k];
            let far = model.spring_ends[spring as usize][1] as usize == v;
            spring | if far { B_END } else { 0 }
        };
        let n = model.vertex_count();
        let none = wgpu::BufferUsages::empty();
        let (entries, offsets, entry_point, constants) = match layout {
            IncidenceLayout::Offsets => {
                let entries: Vec<u32> = (0..n)
                    .flat_map(|v| adjacency.range(v).map(move |k| entry(v, k)))
                    .collect();
                let offsets = adjacency.offsets.clone();
                (entries, Some(offsets), "main", vec![])
            }
            IncidenceLayout::Rows(width) => {
                // The zero force past the springs', negated: -0.0, which adds nothing.
                let padding = model.spring_count() as u32 | B_END;
                let entries: Vec<u32> = (0..n)
                    .flat_map(|v| {
                        let row = adjacency.range(v).map(move |k| entry(v, k));
                        let pad = width as usize - adjacency.range(v).len();
                        row.chain(std::iter::repeat_n(padding, pad))
                    })
                    .collect();
                (
                    entries,
                    None,
                    "rows",
                    vec![("ROW_ENTRIES", f64::from(width))],
                )
            }
        };
        let entries_buffer = storage(context, "incidence entries", &entries, none);
        let offsets_buffer = offsets
            .as_ref()
            .map(|offsets| storage(context, "incidence offsets", offsets, none));
        let kernel = Kernel::with_constants(
            context,
            "accumulate incidence",
            (super::ACCUMULATE_INCIDENCE, entry_point, &constants),
            buffers.vertex_count,
            |current| {
                let mut resources = vec![
                    (0, buffers.model.uniforms_binding(current)),
                    (1, spring_forces.as_entire_binding()),
                    (3, entries_buffer.as_entire_binding()),
                    (4, buffers.forces.as_entire_binding()),
                ];
                if let Some(offsets) = &offsets_buffer {
                    resources.push((2, offsets.as_entire_binding()));
                }
                resources
            },
        )?;
        Ok(Self {
            kernel,
            bytes: offsets.as_deref().map_or(0, bytes_of) + bytes_of(&entries),
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
        // By offsets and in padded rows (the irregular scene's rows pad to 2x its entries):
        // the same sums, bit for bit.
        let sums = [true, false].map(|offsets| {
            let sums = accumulated(Accumulation::Incidence, stretched_scene(), offsets)?;
            assert_close(&sums.actual, &sums.expected, TOLERANCE, "incidence");
            Some(sums.actual)
        });
        if let [Some(offsets), Some(rows)] = sums {
            assert!(offsets == rows, "padded rows change the sums");
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
