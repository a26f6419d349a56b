//! The force tables of the two methods, built once from the model: gather's sliced-ELL
//! adjacency, scatter's spring table and incidence table (see [`crate::kernels`]).

use hooke_core::{Adjacency, Model};

use crate::kernels::{
    B_END, GatherTable, IncidenceTable, IndexRows, RowForm, SpringForces, SpringTable, Stiffness,
    ValueRows,
};
use crate::lanes::{CACHE_LINE, L1_SET_SPAN};
use crate::layout::{LANES, Numbering, Slices};
use crate::{Method, Topology, owned_rows};

pub(crate) fn into_blocks<T: Copy + Default>(values: Vec<T>) -> Vec<[T; LANES]> {
    values
        .chunks(LANES)
        .map(|c| std::array::from_fn(|lane| c.get(lane).copied().unwrap_or_default()))
        .collect()
}

/// The force tables of `method` with every stiffness times `stiffness_scale`.
pub(crate) fn build_topology(
    model: &Model,
    numbering: &Numbering,
    method: Method,
    stiffness_scale: f64,
) -> Topology {
    let scaled;
    let model = if stiffness_scale == 1.0 {
        model
    } else {
        scaled = model.with_stiffness_scale(stiffness_scale);
        &scaled
    };
    match method {
        Method::Gather => Topology::Gather(gather_table(model, numbering)),
        Method::Scatter => {
            let (springs, incidence) = scatter_tables(model, numbering);
            let spring_forces = SpringForces::for_incidence(&incidence, springs.a.len());
            Topology::Scatter {
                springs,
                incidence,
                spring_forces,
            }
        }
    }
}

fn stiffness_of(model: &Model, per_entry: impl FnOnce() -> Vec<f32>) -> Stiffness {
    match model.stiffnesses.first() {
        Some(&first) if model.stiffnesses.iter().all(|k| *k == first) => {
            Stiffness::uniform(first as f32)
        }
        _ => Stiffness::per_entry(into_blocks(per_entry())),
    }
}

/// Whether gather's rows of `model` so numbered gather their neighbours as points (an
/// irregular mesh's, see `IndexRows::new`): gather then adds each spring's force with fused
/// multiply-adds (`kernels::gather_slice`), and scatter stores its springs' stretches to add
/// them the same way ([`SpringTable::stretches`]), so that the two give the same bits. The
/// gather table's own neighbour rows decide ([`neighbor_rows`]), so the two cannot disagree.
pub(crate) fn sums_fused(model: &Model, numbering: &Numbering) -> bool {
    let (_, neighbors) = Slices::build(
        model,
        numbering,
        |_, e| neighbor_of(model, numbering, e),
        |k| k as u32,
    );
    neighbor_rows(numbering, neighbors)
        .point_offsets()
        .is_some()
}

/// Gather's neighbour of adjacency entry `e`, numbered internally.
fn neighbor_of(model: &Model, numbering: &Numbering, e: usize) -> u32 {
    numbering.internal[model.adjacency.neighbors[e] as usize]
}

/// Gather's neighbour rows from each entry's neighbour (a padding lane's its own vertex).
fn neighbor_rows(numbering: &Numbering, neighbors: Vec<u32>) -> IndexRows {
    IndexRows::new(
        into_blocks(neighbors),
        u32::MAX,
        numbering.padded_len,
        // The force pass reads the positions as points when most rows are gathered.
        RowForm::PointsIfGathered,
    )
}

pub(crate) fn gather_table(model: &Model, numbering: &Numbering) -> GatherTable {
    let (slices, entries) = Slices::build(
        model,
        numbering,
        |_, e| {
            let spring = model.adjacency.springs[e] as usize;
            (
                neighbor_of(model, numbering, e),
                model.rest_lengths[spring] as f32,
                model.stiffnesses[spring] as f32,
            )
        },
        |k| (k as u32, 0.0, 0.0),
    );
    GatherTable {
        slices,
        neighbor: neighbor_rows(numbering, entries.iter().map(|e| e.0).collect()),
        rest_length: ValueRows::new(into_blocks(entries.iter().map(|e| e.1).collect())),
        stiffness: stiffness_of(model, || entries.iter().map(|e| e.2).collect()),
    }
}

/// Vertices whose springs the scatter force pass visits together on a structured mesh: their
/// positions (and their springs' far ends, a row of the mesh further on) stay in the
/// second-level cache while the pass visits each kind of spring in turn.
///
/// Not a power of two: a block's groups of springs, one per kind, lie a block's worth of
/// forces apart, and a vertex sums one row from each group and from the groups a mesh row
/// back. With 1,024 first ends (4 KiB of forces per axis and group) all of those rows fell in
/// the same sets of the first-level cache (it repeats every 4 KiB), and on grids whose rows
/// are a multiple of 1,024 vertices so did the rows a mesh row back: some 18 lines for 8
/// ways. On an AMD EPYC VM the summing then took 1.5x the force pass's time at 1024^2 and
/// 2048^2 against 1.06-1.10x at 512^2 (the two kernels' `perf` samples, one thread), and the
/// scatter step grew 1.13-1.28x per spring from 512^2 to 2048^2. With 1,056 (groups two
/// cache lines apart modulo 4 KiB) the summing takes 0.95-1.04x the force pass at every
/// size, and the step grows 0.99-1.02x per spring (see the performance log). 1,024 since 2026-12-02
/// (4,096 before), so that a mesh of 65,536 vertices has blocks enough for a band per
/// thread.
pub(crate) const SPRING_BLOCK: u32 = 1056;

// A block's groups of forces (a float a spring per axis) lie at least two cache lines apart
// modulo the L1's set span, either way round (see above; `lanes` staggers its runs against
// the same conflict).
const _: () = {
    let apart = SPRING_BLOCK as usize * std::mem::size_of::<f32>() % L1_SET_SPAN;
    let margin = 2 * CACHE_LINE;
    assert!(apart >= margin && apart <= L1_SET_SPAN - margin);
    assert!((SPRING_BLOCK as usize).is_multiple_of(LANES));
};

/// A slot of the scatter force pass: a model spring, or zero-force padding (both ends the
/// vertex given) that keeps the next block's rows whole.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub(crate) enum Slot {
    Spring(u32),
    Padding(u32),
}

/// The order the scatter force pass visits springs in. Structured meshes have a handful of
/// index offsets `b - a` (3 on a grid); grouping springs by offset, then by `a`, makes both
/// ends of 8 consecutive springs consecutive vertices, so a row loads with vector loads. The
/// groups are formed within blocks of [`SPRING_BLOCK`] first ends, so the pass reads the
/// positions once rather than once per offset. Other meshes are laid out in rows whose first
/// ends are a slice's vertices (`owned_rows`, which may re-own springs in `ends`), with
/// tails where the summing can take whole rows (none on structured meshes, whose rows load
/// with vector loads anyway).
fn spring_order(
    ends: &mut [[u32; 2]],
    vertices: usize,
    later: impl FnOnce() -> Adjacency,
) -> (Vec<Slot>, owned_rows::Tails) {
    const MAX_CLASSES: usize = 16;
    let offset = |s: u32| i64::from(ends[s as usize][1]) - i64::from(ends[s as usize][0]);
    let mut counts = std::collections::HashMap::<i64, usize>::new();
    for s in 0..ends.len() as u32 {
        *counts.entry(offset(s)).or_default() += 1;
    }
    let mut common: Vec<(usize, i64)> = counts.iter().map(|(o, c)| (*c, *o)).collect();
    common.sort_unstable_by(|a, b| b.cmp(a));
    common.truncate(MAX_CLASSES);
    let covered: usize = common.iter().map(|(c, _)| c).sum();
    if covered * 10 < ends.len() * 9 {
        return owned_rows::order(ends, vertices, &later());
    }
    let class: std::collections::HashMap<i64, usize> = common
        .iter()
        .enumerate()
        .map(|(rank, (_, o))| (*o, rank))
        .collect();
    let key = |s: u32| {
        let [a, b] = ends[s as usize];
        let class = class.get(&offset(s)).copied().unwrap_or(MAX_CLASSES);
        (a / SPRING_BLOCK, class, a, b)
    };
    let mut order: Vec<u32> = (0..ends.len() as u32).collect();
    order.sort_by_cached_key(|&s| key(s));
    let tails = vec![0; vertices / LANES];
    (order.into_iter().map(Slot::Spring).collect(), tails)
}

/// Per internal vertex, its springs to neighbours later in place, in the order it sums them,
/// with the internal index of each other end.
fn later_springs(model: &Model, numbering: &Numbering) -> Adjacency {
    let adjacency = &model.adjacency;
    let mut later = Adjacency {
        offsets: vec![0],
        neighbors: Vec::with_capacity(model.spring_count()),
        springs: Vec::with_capacity(model.spring_count()),
    };
    for k in 0..numbering.padded_len {
        if let Some(&v) = numbering.original.get(k) {
            let range = adjacency.range(v as usize);
            let first = range.end - numbering.later[v as usize] as usize;
            for &e in &numbering.entries[first..range.end] {
                let other = adjacency.neighbors[e as usize];
                later.neighbors.push(numbering.internal[other as usize]);
                later.springs.push(adjacency.springs[e as usize]);
            }
        }
        later.offsets.push(later.springs.len() as u32);
    }
    later
}

/// How the scatter force pass reads the springs: per model spring its ends (owner first),
/// the slots in order, each model spring's slot, and each slice's tail.
struct ScatterOrder {
    ends: Vec<[u32; 2]>,
    slots: Vec<Slot>,
    slot_of: Vec<u32>,
    tails: owned_rows::Tails,
}

impl ScatterOrder {
    fn new(model: &Model, numbering: &Numbering) -> Self {
        let mut ends: Vec<[u32; 2]> = model
            .spring_ends
            .iter()
            .map(|e| {
                let [a, b] = e.map(|v| numbering.internal[v as usize]);
                [a.min(b), a.max(b)]
            })
            .collect();
        let (slots, tails) = spring_order(&mut ends, numbering.padded_len, || {
            later_springs(model, numbering)
        });
        let mut slot_of = vec![0u32; model.spring_count()];
        for (slot, s) in slots.iter().enumerate() {
            if let Slot::Spring(s) = s {
                slot_of[*s as usize] = slot as u32;
            }
        }
        Self {
            ends,
            slots,
            slot_of,
            tails,
        }
    }

    /// The ends of the spring in `slot`, owner first.
    fn slot_ends(&self, slot: Slot) -> [u32; 2] {
        match slot {
            Slot::Spring(s) => self.ends[s as usize],
            Slot::Padding(v) => [v, v],
        }
    }

    /// Per slot, its spring's value, and zero for padding.
    fn per_slot(&self, value: impl Fn(usize) -> f32) -> Vec<f32> {
        let of = |slot: &Slot| match slot {
            Slot::Spring(s) => value(*s as usize),
            Slot::Padding(_) => 0.0,
        };
        self.slots.iter().map(of).collect()
    }
}

/// Per model spring, the entries holding its stiffness in `method`'s table: gather has one at
/// each end, scatter one slot (the other `u32::MAX`). What tearing zeroes in place.
pub(crate) fn stiffness_entries(
    model: &Model,
    numbering: &Numbering,
    method: Method,
) -> Vec<[u32; 2]> {
    let mut entries = vec![[u32::MAX; 2]; model.spring_count()];
    match method {
        Method::Gather => {
            let springs = &model.adjacency.springs;
            let (_, layout) = Slices::build(model, numbering, |_, e| springs[e], |_| u32::MAX);
            for (entry, &s) in layout.iter().enumerate() {
                if let Some(ends) = entries.get_mut(s as usize) {
                    ends[usize::from(ends[0] != u32::MAX)] = entry as u32;
                }
            }
        }
        Method::Scatter => {
            let order = ScatterOrder::new(model, numbering);
            for (ends, slot) in entries.iter_mut().zip(order.slot_of) {
                ends[0] = slot;
            }
        }
    }
    entries
}

pub(crate) fn scatter_tables(
    model: &Model,
    numbering: &Numbering,
) -> (SpringTable, IncidenceTable) {
    let order = ScatterOrder::new(model, numbering);
    let rows = order.slots.len().div_ceil(LANES);
    let zero_slot = (rows * LANES) as u32;
    let adjacency = &model.adjacency;
    let tail = |slice: usize| usize::from(order.tails.get(slice).copied().unwrap_or(0));
    let (slices, entries) = Slices::build_with_tails(
        model,
        numbering,
        |k, e| {
            let spring = adjacency.springs[e] as usize;
            let is_b_end = order.ends[spring][1] as usize == k;
            order.slot_of[spring] | if is_b_end { B_END } else { 0 }
        },
        |_| zero_slot,
        tail,
    );
    let tails = (0..numbering.slice_count())
        .map(|slice| {
            let rows = slices.rows(slice);
            let tail_rows = rows.end - tail(slice)..rows.end;
            let whole = tail_rows.clone().all(|row| {
                let first = entries[row * LANES];
                (0..LANES).all(|lane| entries[row * LANES + lane] == first + lane as u32)
                    && first.is_multiple_of(LANES as u32)
                    && (row == tail_rows.start
                        || entries[(row - 1) * LANES] + LANES as u32 == first)
            });
            // By construction; were it not so, the rows would be gathered like the others.
            debug_assert!(whole, "slice {slice}'s tail is not whole rows");
            if whole { tail(slice) as u8 } else { 0 }
        })
        .collect();
    let stretches = sums_fused(model, numbering);
    let incidence = IncidenceTable {
        slices,
        tails,
        stretches,
        entry: IndexRows::new(
            into_blocks(entries),
            !B_END,
            zero_slot as usize + LANES,
            RowForm::PointsIfGathered,
        ),
    };
    // The force pass reads the positions as points when the spring forces are points, and
    // then every row of both ends as point offsets (rows whose first ends are a slice's
    // vertices load those from the axes).
    let form = if incidence.forces_as_points() {
        RowForm::Points
    } else {
        RowForm::Runs
    };
    let end_rows = |end: usize| {
        let ends = order.slots.iter().map(|&slot| order.slot_ends(slot)[end]);
        IndexRows::new(
            into_blocks(ends.collect()),
            u32::MAX,
            numbering.padded_len,
            form,
        )
    };
    let springs = SpringTable {
        a: end_rows(0),
        b: end_rows(1),
        rest_length: ValueRows::new(into_blocks(
            order.per_slot(|s| model.rest_lengths[s] as f32),
        )),
        stiffness: stiffness_of(model, || order.per_slot(|s| model.stiffnesses[s] as f32)),
        slots: order.slots.len(),
        stretches,
    };
    (springs, incidence)
}

#[cfg(test)]
mod tests {
    use hooke_core::scene::MeshSection;
    use hooke_testkit::benchmark_scene;

    use super::*;
    use crate::layout::VertexOrder;
    use crate::simd::point_slot;

    fn topology_of(mesh: MeshSection, vertices: u32, method: Method) -> Topology {
        let scene = benchmark_scene(mesh, vertices);
        let numbering = Numbering::new(&scene.model, VertexOrder::Auto);
        build_topology(&scene.model, &numbering, method, 1.0)
    }

    fn table_of(mesh: MeshSection, vertices: u32) -> GatherTable {
        match topology_of(mesh, vertices, Method::Gather) {
            Topology::Gather(table) => table,
            Topology::Scatter { .. } => unreachable!("gather builds a gather table"),
        }
    }

    /// Scatter keeps a grid's spring forces in three axes (its incidence rows load with
    /// vector loads) and an irregular mesh's as one point per spring (its rows are gathered
    /// lane by lane), there as stretches, summed as gather sums them. The solver tests on
    /// both kinds of mesh hold either to the same bits.
    #[test]
    fn scatter_stores_spring_forces_as_points_where_incidence_rows_are_gathered() {
        for (mesh, vertices, points) in [
            (MeshSection::unit_grid(64, 64), 64 * 64, false),
            (MeshSection::unit_irregular(4096, 1), 4096, true),
        ] {
            let Topology::Scatter {
                springs,
                incidence,
                spring_forces,
            } = topology_of(mesh.clone(), vertices, Method::Scatter)
            else {
                unreachable!("scatter builds scatter tables");
            };
            let share = incidence.entry.contiguous_share();
            assert_eq!(
                incidence.entry.mostly_gathered(),
                points,
                "contiguous incidence rows: {share}"
            );
            // One row more than the springs, for padding entries.
            let (rows, bytes_per_slot) = match &spring_forces {
                SpringForces::Axes(axes) => (axes.blocks(), 12),
                SpringForces::Points(rows) => (rows.len(), 16),
            };
            assert_eq!(matches!(spring_forces, SpringForces::Points(_)), points);
            // Where gather sums fused (it reads points too), the points are stretches.
            let gathers_points = table_of(mesh, vertices).neighbor.point_offsets().is_some();
            assert_eq!(gathers_points, points);
            assert_eq!((springs.stretches, incidence.stretches), (points, points));
            assert_eq!(rows, springs.a.len() + 1);
            assert_eq!(spring_forces.bytes(), rows * LANES * bytes_per_slot);
        }
    }

    /// A grid's springs are visited block of first ends by block, each block's grouped by
    /// offset, so the force pass reads each position once and nearly every row of 8 still
    /// loads both ends with vector loads.
    #[test]
    fn a_grids_springs_run_by_offset_within_blocks_of_first_ends() {
        let side = 128;
        let Topology::Scatter { springs, .. } = topology_of(
            MeshSection::unit_grid(side, side),
            side * side,
            Method::Scatter,
        ) else {
            unreachable!("scatter builds scatter tables");
        };
        let count = 3 * (side - 1) * (side - 1) + 2 * (side - 1);
        let firsts: Vec<u32> = (0..springs.a.len())
            .flat_map(|row| springs.a.row(row))
            .take(count as usize)
            .collect();
        let blocks: Vec<u32> = firsts.iter().map(|a| a / SPRING_BLOCK).collect();
        assert!(blocks.is_sorted(), "springs leave a block and come back");
        assert_eq!(blocks.last(), Some(&((side * side - 1) / SPRING_BLOCK)));
        // Within a block, the first ends rise three times over: once per offset.
        let restarts = firsts.windows(2).filter(|w| w[1] < w[0]).count();
        assert_eq!(restarts, 2 * (side * side).div_ceil(SPRING_BLOCK) as usize);
        for ends in [&springs.a, &springs.b] {
            let share = ends.contiguous_share();
            assert!(share > 0.95, "contiguous spring-end rows: {share}");
        }
    }

    /// An irregular mesh's springs are re-owned within blocks so that most rows' first ends
    /// are one slice's 8 vertices (three vector loads instead of eight point loads); a spring
    /// across blocks stays with its lower end, and blocks end in whole rows. Its summing takes
    /// some 40% of its rows whole (a row of the force pass each, in lane order: checked as the
    /// table is built).
    #[test]
    fn most_of_an_irregular_meshs_spring_rows_start_at_a_slices_vertices() {
        let Topology::Scatter {
            springs, incidence, ..
        } = topology_of(
            MeshSection::unit_irregular(16384, 1),
            16384,
            Method::Scatter,
        )
        else {
            unreachable!("scatter builds scatter tables");
        };
        let share = springs.a.contiguous_share();
        assert!(share > 0.85, "rows of a slice's vertices: {share}");
        let tails: usize = incidence.tails.iter().map(|&t| usize::from(t)).sum();
        let whole = tails as f64 / (incidence.slices.entry_count() / LANES) as f64;
        assert!(whole > 0.35, "rows summed whole: {whole}");
        let mut last_block = 0;
        for row in 0..springs.slots / LANES {
            let (a, b) = (springs.a.row(row), springs.b.row(row));
            let blocks: Vec<u32> = a.iter().map(|a| a / SPRING_BLOCK).collect();
            assert!(
                blocks.iter().all(|k| *k == blocks[0]),
                "row {row} spans blocks"
            );
            assert!(blocks[0] >= last_block, "row {row} goes back a block");
            last_block = blocks[0];
            for (a, b) in a.into_iter().zip(b) {
                assert!(
                    a / SPRING_BLOCK == b / SPRING_BLOCK || a < b,
                    "{a} owns {b}"
                );
            }
        }
    }

    /// An irregular mesh's rows are stored as point offsets, which read back as the same
    /// indices and flags; a grid's are not.
    #[test]
    fn irregular_rows_are_point_offsets_that_read_back_as_their_indices() {
        let grid = table_of(MeshSection::unit_grid(64, 64), 64 * 64);
        assert!(grid.neighbor.point_offsets().is_none());
        let Topology::Scatter {
            springs, incidence, ..
        } = topology_of(MeshSection::unit_irregular(4096, 1), 4096, Method::Scatter)
        else {
            unreachable!("scatter builds scatter tables");
        };
        let irregular = table_of(MeshSection::unit_irregular(4096, 1), 4096);
        for (rows, mask, limit) in [
            (&irregular.neighbor, u32::MAX, 4096),
            (&springs.a, u32::MAX, 4096),
            (&springs.b, u32::MAX, 4096),
            (&incidence.entry, !B_END, (springs.a.len() + 1) * LANES),
        ] {
            let offsets = rows
                .point_offsets()
                .expect("an irregular mesh's rows are offsets");
            assert_eq!(offsets.len(), rows.len());
            let mut flagged = 0;
            for (row, offsets) in offsets.iter().enumerate() {
                let entries = rows.row(row);
                for (offset, entry) in offsets.iter().zip(entries) {
                    assert_eq!(offset & mask, point_slot(entry & mask) * 16);
                    assert_eq!(offset & !mask, entry & !mask);
                    assert!(((entry & mask) as usize) < limit);
                    flagged += usize::from(entry & !mask != 0);
                }
            }
            // The incidence rows' far ends keep their flag.
            assert_eq!(flagged > 0, mask != u32::MAX);
        }
        // Offsets that would reach the flag bits are not used.
        let rows = vec![[0, 9, 3, 1, 7, 2, 5, 4]; 4];
        assert!(
            IndexRows::new(rows.clone(), !B_END, 1 << 27, RowForm::Points)
                .point_offsets()
                .is_some()
        );
        let too_far = IndexRows::new(rows, !B_END, (1 << 27) + 1, RowForm::Points);
        assert!(too_far.point_offsets().is_none());
        assert_eq!(too_far.row(2), [0, 9, 3, 1, 7, 2, 5, 4]);
    }

    #[test]
    fn a_grid_streams_most_rest_lengths_as_one_value_per_row_and_an_irregular_mesh_none() {
        let grid = table_of(MeshSection::unit_grid(64, 64), 64 * 64);
        let share = grid.rest_length.uniform_share();
        // Rows along the boundary (an eighth at 64^2) mix rest lengths and padding.
        assert!(share > 0.8, "uniform rows of a grid: {share}");
        // 5 bytes a uniform row instead of 32.
        let whole = grid.rest_length.len() * std::mem::size_of::<crate::kernels::Block>();
        assert!(
            grid.rest_length.bytes() < whole / 3,
            "{}",
            grid.rest_length.bytes()
        );
        let irregular = table_of(MeshSection::unit_irregular(4096, 1), 4096);
        assert_eq!(irregular.rest_length.uniform_share(), 0.0);
        assert_eq!(
            irregular.rest_length.bytes(),
            irregular.rest_length.len() * std::mem::size_of::<crate::kernels::Block>()
        );
    }
}
