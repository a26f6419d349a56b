//! Memory layout of the CPU solver: vertex order and sliced adjacency tables.
//!
//! Vertices are processed in slices of [`LANES`] consecutive (internal) vertices, one per SIMD
//! lane. A slice's adjacency is stored entry-major and padded to the slice's largest valence
//! (sliced ELLPACK, "SELL-8"): row `r` of a slice holds the `r`-th incident spring of each of its
//! 8 vertices, so one row is a gather of 8 neighbours. This is the point-centric (PCA) CSR of the
//! paper, laid out for SIMD; sorting vertices by valence ([`VertexOrder::ValenceSorted`]) is the
//! paper's remedy for padding waste, at the price of spatial locality.
//!
//! Both methods keep each vertex's springs in the same order (the model's spring order), so the
//! per-vertex sums of gather and scatter are bit-identical.

use hooke_core::Model;

/// SIMD width of the kernels (8 x f32 = one AVX register).
pub const LANES: usize = 8;

/// The order vertices are stored and processed in.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub enum VertexOrder {
    /// The mesh's own order (best locality for generated grids and most meshes).
    #[default]
    Mesh,
    /// Sorted by decreasing valence, as the paper's GPU texture layout (stable within a valence).
    ValenceSorted,
}

/// The internal numbering of vertices: internal vertex `k` is model vertex `original[k]`.
#[derive(Clone, Debug)]
pub struct Numbering {
    /// Length `n_vertices`: internal -> model vertex.
    pub original: Vec<u32>,
    /// Length `n_vertices`: model -> internal vertex.
    pub internal: Vec<u32>,
    /// Vertex count rounded up to whole slices; the extra lanes are inert padding vertices.
    pub padded_len: usize,
}

impl Numbering {
    pub fn new(model: &Model, order: VertexOrder) -> Self {
        let n = model.vertex_count();
        let mut original: Vec<u32> = (0..n as u32).collect();
        if order == VertexOrder::ValenceSorted {
            original.sort_by_key(|&v| std::cmp::Reverse(model.adjacency.valence(v as usize)));
        }
        let mut internal = vec![0u32; n];
        for (k, &v) in original.iter().enumerate() {
            internal[v as usize] = k as u32;
        }
        Self {
            original,
            internal,
            padded_len: n.div_ceil(LANES) * LANES,
        }
    }

    pub fn slice_count(&self) -> usize {
        self.padded_len / LANES
    }
}

/// A sliced table: `slice_rows[s]..slice_rows[s+1]` are the entry rows of slice `s`; entry
/// `(row, lane)` is at `row * LANES + lane` in the caller's entry arrays.
#[derive(Clone, Debug, Default)]
pub struct Slices {
    /// Length `n_slices + 1`.
    pub slice_rows: Vec<u32>,
}

impl Slices {
    /// Lays out one entry per (vertex, incident spring), in the model's per-vertex order.
    ///
    /// `fill(internal_vertex, adjacency_entry)` gives an entry's value, `pad(internal_vertex)` the
    /// value of a padding entry that must contribute nothing.
    pub fn build<T: Copy>(
        model: &Model,
        numbering: &Numbering,
        fill: impl Fn(usize, usize) -> T,
        pad: impl Fn(usize) -> T,
    ) -> (Self, Vec<T>) {
        let n = model.vertex_count();
        let mut slice_rows = Vec::with_capacity(numbering.slice_count() + 1);
        let mut entries = Vec::with_capacity(2 * model.spring_count() + LANES * 8);
        slice_rows.push(0u32);
        for slice in 0..numbering.slice_count() {
            let vertices = slice * LANES..(slice + 1) * LANES;
            let original = |k: usize| (k < n).then(|| numbering.original[k] as usize);
            let width = vertices
                .clone()
                .filter_map(original)
                .map(|v| model.adjacency.valence(v) as usize)
                .max()
                .unwrap_or(0);
            for row in 0..width {
                for k in vertices.clone() {
                    let entry = original(k)
                        .map(|v| model.adjacency.range(v))
                        .filter(|range| row < range.len())
                        .map(|range| fill(k, range.start + row));
                    entries.push(entry.unwrap_or_else(|| pad(k)));
                }
            }
            let last = *slice_rows.last().unwrap_or(&0);
            slice_rows.push(last + width as u32);
        }
        (Self { slice_rows }, entries)
    }

    pub fn rows(&self, slice: usize) -> std::ops::Range<usize> {
        self.slice_rows[slice] as usize..self.slice_rows[slice + 1] as usize
    }

    pub fn entry_count(&self) -> usize {
        *self.slice_rows.last().unwrap_or(&0) as usize * LANES
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use glam::DVec3;
    use hooke_core::mesh::{GridPlane, grid};
    use hooke_core::{MassModel, ModelOptions, StiffnessModel};

    fn model() -> Model {
        let mesh = grid(5, 3, [1.0, 1.0], GridPlane::Xz, DVec3::ZERO);
        let options = ModelOptions {
            stiffness: StiffnessModel::Uniform(1.0),
            mass: MassModel::PerVertex(1.0),
            rest_length_scale: 1.0,
            pinned: vec![],
        };
        Model::from_mesh(&mesh, &options).expect("model")
    }

    #[test]
    fn every_adjacency_entry_appears_once_and_padding_fills_the_rest() {
        let model = model();
        let numbering = Numbering::new(&model, VertexOrder::ValenceSorted);
        let (slices, entries) = Slices::build(&model, &numbering, |_, e| Some(e), |_| None);
        let mut seen: Vec<usize> = entries.iter().flatten().copied().collect();
        seen.sort_unstable();
        assert_eq!(seen, (0..2 * model.spring_count()).collect::<Vec<_>>());
        assert_eq!(entries.len(), slices.entry_count());
    }

    #[test]
    fn valence_sorted_order_puts_high_valence_first() {
        let model = model();
        let numbering = Numbering::new(&model, VertexOrder::ValenceSorted);
        let valences: Vec<u32> = numbering
            .original
            .iter()
            .map(|&v| model.adjacency.valence(v as usize))
            .collect();
        assert!(valences.windows(2).all(|w| w[0] >= w[1]));
        for (k, &v) in numbering.original.iter().enumerate() {
            assert_eq!(numbering.internal[v as usize] as usize, k);
        }
    }
}
