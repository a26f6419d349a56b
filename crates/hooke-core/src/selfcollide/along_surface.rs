//! Patches grouped along the surface, for a mesh that already lies folded when it is loaded.
//!
//! The culling groups vertices into patches by where they lie (see [`super::Culling`]), in
//! the layout the scene gave them. A mesh loaded from a file in folds (a cloth exported
//! mid-fall, a garment's panels laid close) has no flat layout: grouped by where its vertices
//! lie, a patch holds pieces of two layers, is a pair with itself in contact for good, and its
//! vertices fill none of the solver's blocks. Such a mesh is grouped instead by halving it
//! again and again along its springs, each cut across the piece between two of its ends
//! where it crosses the fewest springs, so every patch is one piece of the surface.
//!
//! What is halved is the owner's blocks ([`LANES`] vertices it keeps side by side), so that
//! each patch is whole blocks, which the culling reads straight from the owner. A solver
//! keeps a mesh in the file's order unless that order scatters neighbours, and a file's order
//! runs along the surface, so its blocks are pieces of one layer where its rows are whole
//! blocks; where they are not, the vertices are halved one by one.

use std::cmp::Reverse;
use std::collections::BinaryHeap;
use std::sync::atomic::{AtomicU32, AtomicU64, Ordering};

use glam::{DVec3, Vec3};
use rayon::prelude::*;

use super::LANES;
use super::culling::{PATCH, morton_order, slots_in};
use crate::{Adjacency, Model};

/// Share of patches, grouped by where the vertices lie, that may hold two layers in contact
/// (see [`layered_patches`]) before grouping along the surface is tried.
const LAYERED_PATCHES: f64 = 0.01;

/// Units below which a half is halved again on the calling thread.
const PARALLEL_UNITS: usize = 512;

/// The order whose runs of [`PATCH`] make `model`'s patches, for an owner that keeps the
/// vertices in the order `places` (its blocks are runs of [`LANES`] of it): the Morton order
/// of the initial positions, unless more than [`LAYERED_PATCHES`] of those patches hold two
/// layers in contact; then the order along the surface ([`along_surface`]) in whole blocks,
/// or else vertex by vertex, whichever first leaves at most half as many patches in pieces
/// ([`split_patches`]). (A patch across a tight crease holds two layers in contact along the
/// surface too; those in pieces are the ones the Morton order made.)
pub fn patch_order(model: &Model, places: &[u32]) -> Vec<u32> {
    let positions: Vec<Vec3> = model
        .initial_positions
        .iter()
        .map(|p| p.as_vec3())
        .collect();
    let by_place = morton_order(&positions);
    let layered = layered_patches(&by_place, model, &positions);
    if layered as f64 <= LAYERED_PATCHES * by_place.len().div_ceil(PATCH) as f64 {
        return by_place;
    }
    let split = split_patches(&by_place, &model.adjacency);
    // Whole blocks need blocks of one layer, which an owner that reorders its vertices (by
    // valence, say) may not keep.
    for unit in [LANES, 1] {
        let along = along_surface(model, places, unit);
        if 2 * split_patches(&along, &model.adjacency) <= split {
            return along;
        }
    }
    by_place
}

/// Where each vertex comes in an order of patches, so that a patch can name its members by a
/// bit each.
struct Slots(Vec<u32>);

impl Slots {
    fn of(order: &[u32]) -> Self {
        Self(slots_in(order))
    }

    /// The bit of vertex `w` among the `members` of patch `patch`; zero if not one of them.
    fn bit_in(&self, w: u32, patch: usize, members: &[u32]) -> u64 {
        let first = patch * PATCH;
        let j = self.0[w as usize] as usize;
        if (first..first + members.len()).contains(&j) {
            1u64 << (j - first)
        } else {
            0
        }
    }
}

/// How many runs of [`PATCH`] in `order` are not joined into one piece by their own springs.
pub fn split_patches(order: &[u32], adjacency: &Adjacency) -> usize {
    let slots = Slots::of(order);
    order
        .par_chunks(PATCH)
        .enumerate()
        .filter(|&(patch, members)| {
            // The members the first one's piece has reached, a bit each, and those whose
            // springs are still to follow.
            let (mut reached, mut frontier) = (1u64, 1u64);
            while frontier != 0 {
                let k = frontier.trailing_zeros() as usize;
                frontier &= frontier - 1;
                for &w in adjacency.neighbors_of(members[k]) {
                    let bit = slots.bit_in(w, patch, members);
                    frontier |= bit & !reached;
                    reached |= bit;
                }
            }
            reached.count_ones() as usize != members.len()
        })
        .count()
}

/// How many runs of [`PATCH`] in `order` hold pieces of two layers of the surface in contact:
/// two vertices closer in `positions` than the shortest spring at either, which no path of two
/// springs joins. (On one layer, a vertex's nearest neighbours are its springs' other ends.)
pub fn layered_patches(order: &[u32], model: &Model, positions: &[Vec3]) -> usize {
    let adjacency = &model.adjacency;
    let slots = Slots::of(order);
    let shortest: Vec<f32> = (0..order.len())
        .map(|v| {
            adjacency
                .range(v)
                .map(|e| model.rest_lengths[adjacency.springs[e] as usize] as f32)
                .fold(f32::INFINITY, f32::min)
        })
        .collect();
    order
        .par_chunks(PATCH)
        .enumerate()
        .filter(|&(patch, members)| {
            let bit_of = |w: u32| slots.bit_in(w, patch, members);
            members.iter().enumerate().any(|(k, &u)| {
                let mut near = 1u64 << k;
                for &w in adjacency.neighbors_of(u) {
                    near |= bit_of(w);
                    for &x in adjacency.neighbors_of(w) {
                        near |= bit_of(x);
                    }
                }
                let at = positions[u as usize];
                members[k + 1..].iter().enumerate().any(|(i, &v)| {
                    let within = shortest[u as usize].min(shortest[v as usize]);
                    near >> (k + 1 + i) & 1 == 0
                        && at.distance_squared(positions[v as usize]) < within * within
                })
            })
        })
        .count()
}

/// Every vertex of `model`, in an order whose runs of [`PATCH`] are pieces of the surface,
/// each made of whole units of `places` (the vertices in their owner's order): runs of `unit`
/// (which divides [`PATCH`]) halved along the springs again and again, each half a whole
/// number of patches. A short last unit goes last.
pub fn along_surface(model: &Model, places: &[u32], unit: usize) -> Vec<u32> {
    let graph = UnitGraph::new(model, places, unit);
    let full = places.len() / unit;
    let mut order: Vec<u32> = (0..full as u32).collect();
    let marks = Marks {
        half: (0..full).map(|_| AtomicU64::new(u64::MAX)).collect(),
        index: (0..full).map(|_| AtomicU32::new(0)).collect(),
    };
    halve(&mut order, 0, &marks, &graph);
    order
        .iter()
        .flat_map(|&b| graph.unit(b as usize))
        .chain(&places[full * unit..])
        .copied()
        .collect()
}

/// Runs of `unit` of the owner's order, joined where a spring joins their vertices, each join
/// as long as the distance between the runs' centres where the mesh was placed (the runs of a
/// join are near each other on the surface, so that is nearly the distance along it).
struct UnitGraph<'a> {
    places: &'a [u32],
    unit: usize,
    offsets: Vec<usize>,
    joins: Vec<Join>,
}

/// Two units that springs join: the other unit, the distance between their centres, and how
/// many springs.
#[derive(Clone, Copy, Debug)]
struct Join {
    unit: u32,
    length: f64,
    springs: u32,
}

impl<'a> UnitGraph<'a> {
    fn new(model: &Model, places: &'a [u32], unit: usize) -> Self {
        let n = model.vertex_count();
        let full = places.len() / unit;
        let mut unit_of = vec![u32::MAX; n];
        for (b, members) in places[..full * unit].chunks(unit).enumerate() {
            for &v in members {
                unit_of[v as usize] = b as u32;
            }
        }
        let centres: Vec<DVec3> = places[..full * unit]
            .chunks(unit)
            .map(|members| {
                members
                    .iter()
                    .map(|&v| model.initial_positions[v as usize])
                    .sum::<DVec3>()
                    / unit as f64
            })
            .collect();
        let rows: Vec<Vec<Join>> = places[..full * unit]
            .par_chunks(unit)
            .enumerate()
            .map(|(b, members)| {
                let mut ends: Vec<u32> = members
                    .iter()
                    .flat_map(|&v| model.adjacency.neighbors_of(v))
                    .map(|&w| unit_of[w as usize])
                    .filter(|&c| c != b as u32 && c != u32::MAX)
                    .collect();
                ends.sort_unstable();
                ends.chunk_by(|a, b| a == b)
                    .map(|run| Join {
                        unit: run[0],
                        length: centres[b].distance(centres[run[0] as usize]),
                        springs: run.len() as u32,
                    })
                    .collect()
            })
            .collect();
        let offsets = std::iter::once(0)
            .chain(rows.iter().scan(0, |end, row| {
                *end += row.len();
                Some(*end)
            }))
            .collect();
        Self {
            places,
            unit,
            offsets,
            joins: rows.into_iter().flatten().collect(),
        }
    }

    fn unit(&self, b: usize) -> &'a [u32] {
        &self.places[b * self.unit..(b + 1) * self.unit]
    }

    fn joins_of(&self, b: u32) -> &[Join] {
        &self.joins[self.offsets[b as usize]..self.offsets[b as usize + 1]]
    }
}

/// Which half each unit is in, and where in it, while it is being halved. Halves being
/// halved at the same time hold different units (atomics only so that threads can share the
/// arrays).
struct Marks {
    half: Vec<AtomicU64>,
    index: Vec<AtomicU32>,
}

/// Orders `units` (those at `start..` of the whole order) so that each run of a patch's
/// worth is a piece of the surface: the units on one side of a cut across the piece first,
/// as many as half the patches, then each half the same way.
fn halve(units: &mut [u32], start: usize, marks: &Marks, graph: &UnitGraph) {
    let len = units.len();
    let patch = PATCH / graph.unit;
    if len <= patch {
        return;
    }
    // A half is its start and length: no two halves alive at once share both.
    let half = (start as u64) << 32 | len as u64;
    for (k, &b) in units.iter().enumerate() {
        marks.half[b as usize].store(half, Ordering::Relaxed);
        marks.index[b as usize].store(k as u32, Ordering::Relaxed);
    }
    let inside = |c: u32| {
        (marks.half[c as usize].load(Ordering::Relaxed) == half)
            .then(|| marks.index[c as usize].load(Ordering::Relaxed) as usize)
    };
    // The piece's two ends: the farthest unit from any, and the farthest from that; then the
    // two ends across it: the farthest from both, and the farthest from that.
    let farthest = |from: &[f64]| {
        (0..len)
            .filter(|&k| from[k].is_finite())
            .max_by(|&a, &b| from[a].total_cmp(&from[b]))
            .unwrap_or(0)
    };
    let a = distances(
        units,
        farthest(&distances(units, 0, &inside, graph)),
        &inside,
        graph,
    );
    let b = distances(units, farthest(&a), &inside, graph);
    let both: Vec<f64> = a.iter().zip(&b).map(|(x, y)| x.min(*y)).collect();
    let c = distances(units, farthest(&both), &inside, graph);
    let d = distances(units, farthest(&c), &inside, graph);
    // Each way across: nearer one end than the other, along the piece, across it, and the two
    // diagonals between (the diameter of a square runs corner to corner, and a cut across it
    // leaves triangles). The cut through the fewest springs leaves the roundest halves.
    let middle = len.div_ceil(patch) / 2 * patch;
    let ways: [&dyn Fn(usize) -> f64; 4] = [
        &|k| a[k] - b[k],
        &|k| c[k] - d[k],
        &|k| (a[k] - b[k]) + (c[k] - d[k]),
        &|k| (a[k] - b[k]) - (c[k] - d[k]),
    ];
    let mut best: Option<(u64, Vec<u32>)> = None;
    let mut first_half = vec![false; len];
    for way in ways {
        // Units of other pieces (not reached) last.
        let side = |k: usize| {
            Some(way(k))
                .filter(|x| x.is_finite())
                .unwrap_or(f64::INFINITY)
        };
        let mut order: Vec<u32> = (0..len as u32).collect();
        order.sort_by(|&x, &y| side(x as usize).total_cmp(&side(y as usize)));
        first_half.fill(false);
        for &k in &order[..middle] {
            first_half[k as usize] = true;
        }
        let cut: u64 = order[..middle]
            .iter()
            .flat_map(|&k| graph.joins_of(units[k as usize]))
            .filter(|join| inside(join.unit).is_some_and(|j| !first_half[j]))
            .map(|join| u64::from(join.springs))
            .sum();
        if best.as_ref().is_none_or(|(fewest, _)| cut < *fewest) {
            best = Some((cut, order));
        }
    }
    let (_, order) = best.expect("four ways");
    let reordered: Vec<u32> = order.iter().map(|&k| units[k as usize]).collect();
    units.copy_from_slice(&reordered);
    let (first, second) = units.split_at_mut(middle);
    if len >= PARALLEL_UNITS {
        rayon::join(
            || halve(first, start, marks, graph),
            || halve(second, start + middle, marks, graph),
        );
    } else {
        halve(first, start, marks, graph);
        halve(second, start + middle, marks, graph);
    }
}

/// The length of the shortest path of joins from `units[from]` to each of `units` that
/// `inside` finds among them (infinite where none), by Dijkstra's search.
fn distances(
    units: &[u32],
    from: usize,
    inside: &impl Fn(u32) -> Option<usize>,
    graph: &UnitGraph,
) -> Vec<f64> {
    let mut distance = vec![f64::INFINITY; units.len()];
    // Lengths are at least zero, so their bits order as they do.
    let mut heap = BinaryHeap::new();
    distance[from] = 0.0;
    heap.push(Reverse((0.0f64.to_bits(), from as u32)));
    while let Some(Reverse((bits, k))) = heap.pop() {
        let d = f64::from_bits(bits);
        if d > distance[k as usize] {
            continue;
        }
        for join in graph.joins_of(units[k as usize]) {
            // A join between units placed where a position is not finite joins nothing.
            if let Some(j) = inside(join.unit).filter(|_| join.length.is_finite()) {
                let through = d + join.length;
                if through < distance[j] {
                    distance[j] = through;
                    heap.push(Reverse((through.to_bits(), j as u32)));
                }
            }
        }
    }
    distance
}

#[cfg(test)]
mod tests {
    use glam::DVec3;

    use super::*;
    use crate::mesh::{GridPlane, grid, irregular};
    use crate::{MassModel, ModelOptions, StiffnessModel};

    fn model_of(mesh: &crate::mesh::Mesh) -> Model {
        let options = ModelOptions {
            stiffness: StiffnessModel::Uniform(10.0),
            mass: MassModel::PerVertex(1.0),
            rest_length_scale: 1.0,
            pinned: vec![],
        };
        Model::from_mesh(mesh, &options).expect("model")
    }

    /// `columns` x `rows` vertices a spring apart, folded across its middle row with the far
    /// half laid a tenth of a spring over the near one.
    fn folded_sheet(columns: u32, rows: u32) -> Model {
        let spacing = 0.01;
        let size = [
            spacing * f64::from(columns - 1),
            spacing * f64::from(rows - 1),
        ];
        let mut model = model_of(&grid(columns, rows, size, GridPlane::Xy, DVec3::ZERO));
        for p in &mut model.initial_positions {
            if p.y > 0.0 {
                *p = DVec3::new(p.x, -p.y, 0.1 * spacing);
            }
        }
        model
    }

    fn positions(model: &Model) -> Vec<Vec3> {
        model
            .initial_positions
            .iter()
            .map(|p| p.as_vec3())
            .collect()
    }

    fn mesh_order(model: &Model) -> Vec<u32> {
        (0..model.vertex_count() as u32).collect()
    }

    #[test]
    fn a_flat_mesh_keeps_the_morton_order_of_its_layout() {
        for mesh in [
            grid(64, 64, [1.0, 1.0], GridPlane::Xz, DVec3::ZERO),
            grid(45, 37, [1.0, 0.8], GridPlane::Xy, DVec3::ZERO),
            irregular(5000, [1.0, 1.0], 3, GridPlane::Xz, DVec3::ZERO),
        ] {
            let model = model_of(&mesh);
            let by_place = morton_order(&positions(&model));
            assert_eq!(layered_patches(&by_place, &model, &positions(&model)), 0);
            assert_eq!(patch_order(&model, &mesh_order(&model)), by_place);
        }
    }

    #[test]
    fn a_folded_mesh_is_grouped_in_pieces_of_its_surface() {
        // Rows of whole blocks, then rows whose blocks wrap from one row's end to the next
        // row's start (two pieces of the sheet): those are grouped a vertex at a time. Neither
        // has a whole number of patches.
        for (columns, unit) in [(48, LANES), (47, 1)] {
            let model = folded_sheet(columns, 48);
            let at = positions(&model);
            let by_place = morton_order(&at);
            let layered = layered_patches(&by_place, &model, &at);
            assert!(layered > by_place.len() / PATCH / 2, "{layered}");
            assert!(split_patches(&by_place, &model.adjacency) > by_place.len() / PATCH / 2);
            let order = patch_order(&model, &mesh_order(&model));
            assert_eq!(order, along_surface(&model, &mesh_order(&model), unit));
            assert_eq!(
                split_patches(&order, &model.adjacency),
                0,
                "{columns} columns"
            );
        }
    }

    #[test]
    fn along_the_surface_every_vertex_comes_once_in_whole_units() {
        let model = folded_sheet(29, 31);
        let n = model.vertex_count();
        // The owner's order: the mesh's, reversed, so units are not runs of vertex numbers.
        let places: Vec<u32> = (0..n as u32).rev().collect();
        for unit in [1, LANES] {
            let order = along_surface(&model, &places, unit);
            let mut sorted = order.clone();
            sorted.sort_unstable();
            assert_eq!(sorted, mesh_order(&model), "unit {unit}");
            let full = n / unit * unit;
            for run in order[..full].chunks(unit) {
                let first = places.iter().position(|&v| v == run[0]).expect("a vertex");
                assert_eq!(first % unit, 0, "unit {unit}");
                assert_eq!(run, &places[first..first + unit], "unit {unit}");
            }
            assert_eq!(order[full..], places[full..], "unit {unit}");
            // Wrapping blocks make pieces of patches in whole blocks (see above).
            if unit == 1 {
                assert_eq!(split_patches(&order, &model.adjacency), 0);
            }
        }
    }

    #[test]
    fn separate_pieces_are_grouped_apart() {
        // Two sheets, unjoined, one laid on the other: no patch may hold vertices of both.
        let mesh = grid(24, 24, [0.23, 0.23], GridPlane::Xz, DVec3::ZERO);
        let mut both = mesh.clone();
        let n = mesh.positions.len() as u32;
        both.positions.extend(
            mesh.positions
                .iter()
                .map(|p| *p + DVec3::new(0.0, 0.001, 0.0)),
        );
        both.triangles
            .extend(mesh.triangles.iter().map(|t| t.map(|v| v + n)));
        let model = model_of(&both);
        let order = patch_order(&model, &mesh_order(&model));
        assert_ne!(order, morton_order(&positions(&model)));
        for members in order.chunks(PATCH) {
            let upper = members.iter().filter(|&&v| v >= n).count();
            assert!(upper == 0 || upper == members.len(), "{members:?}");
        }
    }
}
