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
use hooke_core::mesh::{axes_by_extent, bounds};

/// SIMD width of the kernels (8 x f32 = one AVX register).
pub const LANES: usize = 8;

/// The order vertices are stored and processed in. Results are the same in every order (each
/// vertex sums its springs in the model's order); only speed differs.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub enum VertexOrder {
    /// The mesh's order where its neighbours are near each other in memory, else
    /// [`VertexOrder::Spatial`]: a mesh numbered at random (exported without care for
    /// locality) then runs as fast as one numbered row by row.
    #[default]
    Auto,
    /// The mesh's own order (best locality for generated grids and most meshes).
    Mesh,
    /// In rows through space (see `row_keys`): vertices near each other in space are near
    /// each other in memory, and a grid gets its row-by-row order back.
    Spatial,
    /// Sorted by decreasing valence, as the paper's GPU texture layout (stable within a valence).
    ValenceSorted,
}

impl VertexOrder {
    /// What the solver's description says of it.
    pub fn name(self) -> &'static str {
        match self {
            Self::Auto => "auto",
            Self::Mesh => "mesh order",
            Self::Spatial => "spatial order",
            Self::ValenceSorted => "valence-sorted",
        }
    }
}

/// The internal numbering of vertices: internal vertex `k` is model vertex `original[k]`.
#[derive(Clone, Debug)]
pub struct Numbering {
    /// The order chosen (never [`VertexOrder::Auto`]).
    pub order: VertexOrder,
    /// Whether [`VertexOrder::Auto`] then sorted each window of [`VALENCE_WINDOW`] vertices by
    /// valence, to pad slices less.
    pub valence_windows: bool,
    /// Length `n_vertices`: internal -> model vertex.
    pub original: Vec<u32>,
    /// Length `n_vertices`: model -> internal vertex.
    pub internal: Vec<u32>,
    /// Length `2 n_springs`: the model's adjacency entries, each vertex's (its
    /// `adjacency.range`) sorted by where the neighbour lies (`row_keys`), the order in which
    /// every method sums a vertex's springs. It depends on the geometry alone, so every
    /// numbering sums alike and gives the same bits; on a grid numbered row by row it is the
    /// model's own order.
    pub entries: Vec<u32>,
    /// Length `n_vertices`, by model vertex: how many of its neighbours lie after it in that
    /// order of places, which are the last of its `entries`. Scatter's summing loads such
    /// springs a row at a time where a slice's vertices own equally many (`tables`).
    pub later: Vec<u32>,
    /// Vertex count rounded up to whole slices; the extra lanes are inert padding vertices.
    pub padded_len: usize,
}

/// Springs whose ends are further apart in the numbering than this many "rows" of a square
/// mesh (the square root of the vertex count) count as far; [`VertexOrder::Auto`] renumbers a
/// mesh when more than [`SCATTERED_FRACTION`] of its springs are. A grid or an irregular mesh
/// numbered row by row has none (its neighbours are at most a row and a bit apart), a shuffled
/// one nearly all.
const FAR_ROWS: f64 = 4.0;
const SCATTERED_FRACTION: f64 = 0.05;

/// Vertices per window that [`VertexOrder::Auto`] sorts by valence when slices would be padded
/// more than [`PADDED_FRACTION`] (SELL-C-sigma): a slice's 8 vertices then have nearly equal
/// valences, so few entries are padding, while vertices move at most a window away, so
/// neighbours stay nearly as close in memory as before. A grid's slices are barely padded
/// (only its border has other valences) and are left alone. Within a valence, vertices are
/// sorted by their neighbours later in place ([`Numbering::later`]), so that a slice's
/// vertices have equally many of those too (see `tables`).
pub const VALENCE_WINDOW: usize = 256;
const PADDED_FRACTION: f64 = 0.1;

impl Numbering {
    pub fn new(model: &Model, order: VertexOrder) -> Self {
        let n = model.vertex_count();
        let automatic = order == VertexOrder::Auto;
        let order = match order {
            VertexOrder::Auto if is_scattered(model) => VertexOrder::Spatial,
            VertexOrder::Auto => VertexOrder::Mesh,
            chosen => chosen,
        };
        let keys = row_keys(model);
        let by_place = |a: u32, b: u32| {
            let (ka, kb) = (keys[a as usize], keys[b as usize]);
            ka.0.cmp(&kb.0).then(ka.1.total_cmp(&kb.1))
        };
        let mut original: Vec<u32> = (0..n as u32).collect();
        match order {
            VertexOrder::ValenceSorted => {
                original.sort_by_key(|&v| std::cmp::Reverse(model.adjacency.valence(v as usize)));
            }
            VertexOrder::Spatial => original.sort_by(|a, b| by_place(*a, *b)),
            VertexOrder::Auto | VertexOrder::Mesh => {}
        }
        let adjacency = &model.adjacency;
        let valence = |v: u32| adjacency.valence(v as usize);
        let later: Vec<u32> = (0..n as u32)
            .map(|v| {
                let neighbors = &adjacency.neighbors[adjacency.range(v as usize)];
                let after = neighbors.iter().filter(|&&w| by_place(v, w).is_lt());
                after.count() as u32
            })
            .collect();
        let valence_windows = automatic && padded_fraction(&original, &valence) > PADDED_FRACTION;
        if valence_windows {
            for window in original.chunks_mut(VALENCE_WINDOW) {
                window.sort_by_key(|&v| {
                    (
                        std::cmp::Reverse(valence(v)),
                        std::cmp::Reverse(later[v as usize]),
                    )
                });
            }
        }
        let mut entries: Vec<u32> = (0..adjacency.neighbors.len() as u32).collect();
        for v in 0..n {
            // Stable: neighbours at one place (coincident vertices) keep the model's order.
            entries[adjacency.range(v)].sort_by(|a, b| {
                by_place(
                    adjacency.neighbors[*a as usize],
                    adjacency.neighbors[*b as usize],
                )
            });
        }
        let mut internal = vec![0u32; n];
        for (k, &v) in original.iter().enumerate() {
            internal[v as usize] = k as u32;
        }
        Self {
            order,
            valence_windows,
            original,
            internal,
            entries,
            later,
            padded_len: n.div_ceil(LANES) * LANES,
        }
    }

    pub fn slice_count(&self) -> usize {
        self.padded_len / LANES
    }
}

/// The share of a sliced table's entries that would be padding with vertices in `order`.
fn padded_fraction(order: &[u32], valence: &dyn Fn(u32) -> u32) -> f64 {
    let (mut entries, mut slots) = (0u64, 0u64);
    for slice in order.chunks(LANES) {
        let valences = slice.iter().map(|&v| u64::from(valence(v)));
        entries += valences.clone().sum::<u64>();
        slots += LANES as u64 * valences.max().unwrap_or(0);
    }
    if slots == 0 {
        0.0
    } else {
        1.0 - entries as f64 / slots as f64
    }
}

/// Whether the model's numbering puts many neighbours far apart (see [`FAR_ROWS`]).
fn is_scattered(model: &Model) -> bool {
    let springs = model.spring_ends.len();
    if springs == 0 {
        return false;
    }
    let far = (FAR_ROWS * (model.vertex_count() as f64).sqrt()).max(64.0) as u32;
    let scattered = model
        .spring_ends
        .iter()
        .filter(|[a, b]| a.abs_diff(*b) > far)
        .count();
    scattered as f64 > SCATTERED_FRACTION * springs as f64
}

/// Sort keys that number vertices in rows, as meshing tools and the grid generator do: rows
/// one shortest-spring apart across the sheet's second-longest extent, each row along its
/// longest. On a grid this is its row-by-row order again, so the kernels' rows of 8
/// neighbours stay consecutive and load with one vector load; a space-filling curve keeps
/// neighbours as close but breaks those runs (measured: 2.1x the grid's gather time at 256^2
/// for a Z-order curve, against 1.0-1.1x for rows).
fn row_keys(model: &Model) -> Vec<(i64, f64)> {
    let positions = &model.initial_positions;
    let (low, high) = bounds(positions);
    let extent = high - low;
    let [along, across, _] = axes_by_extent(extent);
    // The row height: the median over vertices of the shortest spring at each.
    let mut shortest: Vec<f64> = (0..model.vertex_count())
        .filter_map(|v| {
            model
                .adjacency
                .range(v)
                .map(|e| model.rest_lengths[model.adjacency.springs[e] as usize])
                .min_by(f64::total_cmp)
        })
        .filter(|l| *l > 0.0)
        .collect();
    let height = if shortest.is_empty() {
        extent[across].max(f64::MIN_POSITIVE)
    } else {
        let middle = shortest.len() / 2;
        *shortest.select_nth_unstable_by(middle, f64::total_cmp).1
    };
    positions
        .iter()
        .map(|p| {
            let row = ((p[across] - low[across]) / height).round() as i64;
            (row, p[along])
        })
        .collect()
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
        Self::build_with_tails(model, numbering, fill, pad, |_| 0)
    }

    /// [`Slices::build`] with the last `tail(slice)` rows of each slice holding each vertex's
    /// last `tail(slice)` entries (none may have fewer), its padding put before them. A lane
    /// then adds the same values in the same order, and its padding's zero forces (`+0`)
    /// elsewhere, which gives the same bits: a sum starts at `+0`, so it is never `-0` (only
    /// `-0 + -0` is), and `+0` added to anything else leaves it as it is.
    pub fn build_with_tails<T: Copy>(
        model: &Model,
        numbering: &Numbering,
        fill: impl Fn(usize, usize) -> T,
        pad: impl Fn(usize) -> T,
        tail: impl Fn(usize) -> usize,
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
            let tail = tail(slice);
            for row in 0..width {
                for k in vertices.clone() {
                    let entry = original(k)
                        .map(|v| model.adjacency.range(v))
                        .and_then(|range| {
                            // Row `row` of `width` holds entry `row`, or in the tail one from the end.
                            let from_end = width - row;
                            let at = if from_end <= tail {
                                range.len().checked_sub(from_end)
                            } else {
                                Some(row).filter(|&r| r + tail < range.len())
                            };
                            at.map(|at| fill(k, numbering.entries[range.start + at] as usize))
                        });
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

    /// Unit springs and masses, nothing pinned.
    fn options() -> ModelOptions {
        ModelOptions {
            stiffness: StiffnessModel::Uniform(1.0),
            mass: MassModel::PerVertex(1.0),
            rest_length_scale: 1.0,
            pinned: vec![],
        }
    }

    fn model() -> Model {
        let mesh = grid(5, 3, [1.0, 1.0], GridPlane::Xz, DVec3::ZERO);
        Model::from_mesh(&mesh, &options()).expect("model")
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
    fn auto_keeps_a_grid_in_order_and_renumbers_a_shuffled_one_along_space() {
        let options = options();
        let mesh = grid(64, 64, [1.0, 1.0], GridPlane::Xz, DVec3::ZERO);
        let ordered = Model::from_mesh(&mesh, &options).expect("model");
        assert_eq!(
            Numbering::new(&ordered, VertexOrder::Auto).order,
            VertexOrder::Mesh
        );
        let shuffled = Model::from_mesh(&mesh.shuffled(1), &options).expect("model");
        let numbering = Numbering::new(&shuffled, VertexOrder::Auto);
        assert_eq!(numbering.order, VertexOrder::Spatial);
        // Numbered in rows again: the grid's own order comes back.
        let span = |numbering: &Numbering, model: &Model| {
            let internal = |v: u32| i64::from(numbering.internal[v as usize]);
            let total: i64 = model
                .spring_ends
                .iter()
                .map(|[a, b]| (internal(*a) - internal(*b)).abs())
                .sum();
            total as f64 / model.spring_count() as f64
        };
        let row_order = span(&Numbering::new(&ordered, VertexOrder::Mesh), &ordered);
        let shuffled_order = span(&Numbering::new(&shuffled, VertexOrder::Mesh), &shuffled);
        let spatial = span(&numbering, &shuffled);
        assert!(shuffled_order > 1000.0, "{shuffled_order}");
        assert_eq!(spatial, row_order);
    }

    #[test]
    fn auto_sorts_an_irregular_mesh_by_valence_in_windows_and_pads_less() {
        let options = options();
        let grid = Model::from_mesh(
            &grid(64, 64, [1.0, 1.0], GridPlane::Xz, DVec3::ZERO),
            &options,
        )
        .expect("model");
        assert!(!Numbering::new(&grid, VertexOrder::Auto).valence_windows);
        let mesh = hooke_core::mesh::irregular(4096, [1.0, 1.0], 1, GridPlane::Xz, DVec3::ZERO);
        let model = Model::from_mesh(&mesh, &options).expect("model");
        let valence = |v: u32| model.adjacency.valence(v as usize);
        let plain = Numbering::new(&model, VertexOrder::Mesh);
        let windowed = Numbering::new(&model, VertexOrder::Auto);
        assert!(windowed.valence_windows);
        let (before, after) = (
            padded_fraction(&plain.original, &valence),
            padded_fraction(&windowed.original, &valence),
        );
        assert!(before > 0.2 && after < 0.05, "{before} -> {after}");
        // No vertex leaves its window.
        for (k, &v) in windowed.original.iter().enumerate() {
            assert_eq!(k / VALENCE_WINDOW, v as usize / VALENCE_WINDOW);
        }
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
