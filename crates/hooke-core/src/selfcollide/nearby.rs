//! The vertices a local pass sorts: the suspects, and every vertex that may share a grid cell
//! with one. A window holds only vertices of its own cell, so with these the local pass sees
//! the same windows as a pass over every vertex, while sorting a few thousand vertices instead
//! of all of them (and computing only their keys).
//!
//! A cleared vertex never moves and lies in its patch's box of the last proof. A suspect that
//! has travelled less than the margin lies within that distance of the box its patch's
//! suspects lay in at the proof; one that has travelled further is covered where it now is.
//! Two points of one cell are less than a cell apart along every axis, so the patches whose
//! boxes come that close (and the margin) hold every vertex a suspect can share a cell with.

use glam::Vec3;
use rayon::prelude::*;

use super::culling::PATCH;
use super::disjoint::Disjoint;
use super::{Culling, Points};

/// How far a vertex has travelled this step (the sum of its moves' lengths), and how far it
/// had when it last widened the suspects, m.
#[derive(Clone, Copy, Debug, Default)]
struct Travel {
    travelled: f32,
    widened_at: f32,
}

/// A local step's vertices, kept by the resolver so a step allocates nothing.
#[derive(Debug, Default)]
pub(super) struct Nearby {
    /// The vertices, ascending (so the sort's ties fall in vertex order, as in a full pass).
    vertices: Vec<u32>,
    /// Their positions, moved by the step's passes so far.
    positions: Vec<Vec3>,
    /// Whether each is a suspect of the culling, whose window a pass tests: a flag beside
    /// the vertex, where the culling's is two loads away at random addresses (its patch,
    /// then the patch's flag), which took a third of the window tests' time.
    suspects: Vec<bool>,
    /// The slots made suspects since the vertices were last listed, in order (a flag is
    /// only ever set within a step).
    flagged: Vec<u32>,
    /// The positions before the last [`Nearby::gather`], kept for the next.
    earlier_positions: Vec<Vec3>,
    /// How far each has travelled this step, in the same order (zero but at `movers`), and
    /// the slots of those that have: kept by slot, beside the positions a move writes, where
    /// they were kept by mesh vertex, each move reading and writing arrays of the whole mesh
    /// at random addresses.
    travels: Vec<Travel>,
    movers: Vec<u32>,
    /// The movers' travels by vertex while [`Nearby::gather`] renumbers the slots.
    carried: Vec<(u32, Travel)>,
    /// Each mesh vertex's index in `vertices`, `u32::MAX` for the others.
    slots: Vec<u32>,
    /// `vertices` as a bit per mesh vertex (what `gather` lists in order).
    marks: Vec<u64>,
    /// Marks in the words of `marks` before each (a vertex's slot, less the marks below it in
    /// its own word).
    ranks: Vec<u32>,
    /// The patches covered, a flag each, and in the order covered.
    covered: Vec<bool>,
    covered_list: Vec<u32>,
    /// How many of the culling's suspect patches are covered.
    suspects_covered: usize,
    /// The patches near where vertices that travelled past the margin have got to, found by
    /// their widenings (see [`Nearby::apply`]), still to be covered.
    pending: Vec<u32>,
}

impl Nearby {
    /// Starts a step of `n` vertices in `patches` patches, covering nothing.
    pub fn begin(&mut self, n: usize, patches: usize) {
        self.clear();
        self.slots.resize(n, u32::MAX);
        self.marks.resize(n.div_ceil(64), 0);
        self.covered.resize(patches, false);
    }

    /// Ends a step: everything back to empty (only what the step touched is cleared).
    pub fn clear(&mut self) {
        for &v in &self.vertices {
            self.slots[v as usize] = u32::MAX;
            self.marks[v as usize / 64] = 0;
        }
        for &p in &self.covered_list {
            self.covered[p as usize] = false;
        }
        for &slot in &self.movers {
            self.travels[slot as usize] = Travel::default();
        }
        self.movers.clear();
        self.vertices.clear();
        self.positions.clear();
        self.suspects.clear();
        self.flagged.clear();
        self.covered_list.clear();
        self.suspects_covered = 0;
        self.pending.clear();
    }

    /// Notes that a vertex has travelled past the margin to `point`, as a widening in
    /// [`Nearby::apply`] does: the next [`Nearby::cover`] covers every vertex that may share a
    /// cell `cell_size` wide with it there or within a margin of it.
    #[cfg(test)]
    pub fn moved_far(&mut self, culling: &Culling, point: Vec3, cell_size: f32) {
        let reach = cover_reach(culling, cell_size);
        culling.patches_near(point, point, reach, |p| self.pending.push(p));
    }

    /// Adds every vertex that may share a cell `cell_size` wide with a suspect of `culling`,
    /// or with a vertex where a widening in [`Nearby::apply`] found it; the new vertices'
    /// positions are read from `points` (they have not moved).
    pub fn cover<P: Points + ?Sized>(&mut self, culling: &Culling, points: &P, cell_size: f32) {
        let reach = cover_reach(culling, cell_size);
        let mut added = Vec::new();
        let mut add = |p: u32| added.push(p);
        let new_suspects = &culling.suspect_patches()[self.suspects_covered..];
        for &p in new_suspects {
            let (low, high) = culling.suspect_box_of(p);
            culling.patches_near(low, high, reach, &mut add);
        }
        self.suspects_covered = culling.suspect_patches().len();
        // A vertex that widened the suspects where it got to may travel a margin further
        // before it widens them again: the patches within reach of there, found then.
        added.append(&mut self.pending);
        let before = self.covered_list.len();
        for p in added {
            if !self.covered[p as usize] {
                self.covered[p as usize] = true;
                self.covered_list.push(p);
                for &v in culling.members_of(p) {
                    self.marks[v as usize / 64] |= 1 << (v % 64);
                }
            }
        }
        if self.covered_list.len() > before {
            // Lists every covered vertex again, each with its patch's flag as it is now.
            self.gather(culling, points, before);
        } else {
            // Only patches with vertices made suspect since they were covered (every suspect
            // is covered by now: the patches near its box include its own) have flags to set.
            for &p in new_suspects {
                let bits = culling.suspect_bits_of(p);
                for (k, &v) in culling.members_of(p).iter().enumerate() {
                    if bits >> k & 1 != 0 {
                        let slot = self.slots[v as usize];
                        let flag = &mut self.suspects[slot as usize];
                        if !*flag {
                            *flag = true;
                            self.flagged.push(slot);
                        }
                    }
                }
            }
        }
    }

    /// Lists the marked vertices in order, with their positions: the step's own for those
    /// of patches covered before `covered_list[first_new]`, `points`' for the others. Each
    /// vertex's slot is its rank among the marks, so the patches are listed in parallel,
    /// each writing its members' slots, and a new patch is read a block at a time
    /// ([`Points::gather_into`]): read vertex by vertex in vertex order, from all over the
    /// owner's store, they took 9 ns each (a step's covering at 512^2 in contact, on one
    /// thread). Listed on one thread, this was three quarters of the covering's time.
    fn gather<P: Points + ?Sized>(&mut self, culling: &Culling, points: &P, first_new: usize) {
        std::mem::swap(&mut self.positions, &mut self.earlier_positions);
        // The movers' travels go with their vertices to their new slots (only they are not
        // zero), read out here while the old slots hold. A slot listed twice (its first move
        // too short to count) is carried once; a travel still zero is not carried at all:
        // a listing adds vertices, after which the sorts made ahead no longer hold and each
        // later pass sorts on its own, without asking which vertices moved (see `ahead`).
        self.carried.clear();
        for slot in self.movers.drain(..) {
            let travel = std::mem::take(&mut self.travels[slot as usize]);
            if travel.travelled != 0.0 {
                self.carried.push((self.vertices[slot as usize], travel));
            }
        }
        // Marks in the words before each word: a vertex's slot is that plus the marks below
        // it in its own word.
        self.ranks.clear();
        let mut total = 0;
        for &word in &self.marks {
            self.ranks.push(total);
            total += word.count_ones();
        }
        let total = total as usize;
        self.vertices.clear();
        self.vertices.resize(total, 0);
        self.positions.clear();
        self.positions.resize(total, Vec3::ZERO);
        self.suspects.clear();
        self.suspects.resize(total, false);
        let (marks, ranks) = (&self.marks[..], &self.ranks[..]);
        let rank = |v: u32| {
            let (w, bit) = (v as usize / 64, v % 64);
            (ranks[w] + (marks[w] & ((1u64 << bit) - 1)).count_ones()) as usize
        };
        let (earlier, slots) = (&self.earlier_positions[..], &self.slots[..]);
        let vertices = Disjoint::new(&mut self.vertices);
        let positions = Disjoint::new(&mut self.positions);
        let suspects = Disjoint::new(&mut self.suspects);
        self.covered_list
            .par_iter()
            .enumerate()
            // A patch is 64 vertices: tasks of a few patches each.
            .with_min_len(16)
            .for_each_init(
                || [[0f32; PATCH]; 3],
                |frame, (i, &p)| {
                    let new = i >= first_new;
                    if new {
                        let [x, y, z] = frame;
                        points.gather_into(culling.places_of(p), [x, y, z]);
                    }
                    let suspects_of_p = culling.suspect_bits_of(p);
                    for (k, &v) in culling.members_of(p).iter().enumerate() {
                        let position = if new {
                            Vec3::new(frame[0][k], frame[1][k], frame[2][k])
                        } else {
                            earlier[slots[v as usize] as usize]
                        };
                        let slot = rank(v);
                        // SAFETY: a slot is its vertex's rank among the marked vertices, so
                        // distinct vertices have distinct slots; every vertex is a member of
                        // one patch, and `covered_list` holds every patch once, so no two
                        // tasks list one vertex.
                        #[allow(unsafe_code)]
                        unsafe {
                            vertices.write(slot, v);
                            positions.write(slot, position);
                            suspects.write(slot, suspects_of_p >> k & 1 != 0);
                        }
                    }
                },
            );
        debug_assert!(self.vertices.is_sorted_by(|a, b| a < b));
        self.flagged.clear();
        let slots = Disjoint::new(&mut self.slots);
        self.vertices
            .par_iter()
            .enumerate()
            .with_min_len(4096)
            .for_each(|(slot, &v)| {
                // SAFETY: the vertices are distinct: each marked vertex was written once, at
                // its own rank (above).
                #[allow(unsafe_code)]
                unsafe {
                    slots.write(v as usize, slot as u32)
                };
            });
        self.travels.resize(total, Travel::default());
        for &(v, travel) in &self.carried {
            let slot = self.slots[v as usize];
            self.travels[slot as usize] = travel;
            self.movers.push(slot);
        }
    }

    /// The vertices, ascending.
    pub fn vertices(&self) -> &[u32] {
        &self.vertices
    }

    /// Their positions, in the same order.
    pub fn positions(&self) -> &[Vec3] {
        &self.positions
    }

    /// Whether each is one of the culling's suspects, in the same order.
    pub fn suspects(&self) -> &[bool] {
        &self.suspects
    }

    /// The slots made suspects since the vertices were last listed (which renumbers them),
    /// in the order made.
    pub fn flagged(&self) -> &[u32] {
        &self.flagged
    }

    /// Moves the vertices at the slots of `moves` (each slot once) and counts each move into
    /// its vertex's travel this step. A vertex that has now travelled `limit` further than
    /// when it last widened the suspects widens them where it is: `widen` gets its position
    /// and adds the patches within [`cover_reach`] of it, which the next [`Nearby::cover`]
    /// covers too.
    pub fn apply(
        &mut self,
        moves: &[(u32, Vec3)],
        limit: f32,
        mut widen: impl FnMut(Vec3, &mut Vec<u32>),
    ) {
        for &(slot, c) in moves {
            let slot = slot as usize;
            self.positions[slot] += c;
            let travel = &mut self.travels[slot];
            if travel.travelled == 0.0 {
                self.movers.push(slot as u32);
            }
            travel.travelled += c.length();
            if travel.travelled - travel.widened_at >= limit {
                travel.widened_at = travel.travelled;
                widen(self.positions[slot], &mut self.pending);
            }
        }
    }

    /// The slots of the vertices that have moved this step, in no set order (a slot whose
    /// first move was too short to add to its travel may be listed twice).
    pub fn movers(&self) -> &[u32] {
        &self.movers
    }

    /// Where vertex `v` (covered) is now.
    #[cfg(test)]
    pub fn position(&self, v: u32) -> Vec3 {
        self.positions[self.slots[v as usize] as usize]
    }
}

/// How far from a suspect's box (or a point a vertex travelled to) a patch's box may lie and
/// hold a vertex that shares a cell `cell_size` wide with it (a tenth of a percent for the
/// cells' rounding), or will within a margin's travel.
pub fn cover_reach(culling: &Culling, cell_size: f32) -> f32 {
    cell_size * 1.001 + culling.margin()
}

#[cfg(test)]
mod tests {
    use std::collections::HashSet;

    use rand::SeedableRng;

    use super::*;
    use crate::Adjacency;
    use crate::selfcollide::culling::tests::{folding_sheet, grid_springs};
    use crate::selfcollide::{GridKeys, Proof, SelfCollision};

    const SIDE: u32 = 40;
    const SPACING: f32 = 0.01;

    /// Covers the suspects of `positions` (when the proof is local) and a point a vertex
    /// travelled to, and checks that every vertex sharing a cell of any grid with one of
    /// them is covered. Returns how many checked vertices were not suspects, or `None` if the
    /// proof was not local.
    fn check_cover(
        positions: &[Vec3],
        adjacency: &Adjacency,
        config: &SelfCollision,
        culling: &mut Culling,
        nearby: &mut Nearby,
        travelled_to: impl Fn(&Culling) -> Vec3,
    ) -> Option<usize> {
        if culling.prove(positions, adjacency, config.distance as f32) != Proof::Local {
            return None;
        }
        nearby.begin(positions.len(), culling.patch_count());
        let point = travelled_to(culling);
        nearby.moved_far(culling, point, config.cell_size as f32);
        nearby.cover(culling, positions, config.cell_size as f32);
        let covered: HashSet<u32> = nearby.vertices().iter().copied().collect();
        assert!(nearby.vertices().is_sorted());
        for ((&v, &x), &suspect) in nearby
            .vertices()
            .iter()
            .zip(nearby.positions())
            .zip(nearby.suspects())
        {
            assert_eq!(x, positions[v as usize]);
            assert_eq!(suspect, culling.is_suspect(v), "vertex {v}");
        }
        let mut beyond_suspects = 0;
        for k in 0..config.grids {
            let keys = GridKeys::new(positions.len(), config, k);
            let mut cells: HashSet<_> = culling
                .suspects()
                .iter()
                .map(|&s| keys.cell(positions[s as usize]))
                .collect();
            cells.insert(keys.cell(point));
            for (v, &x) in positions.iter().enumerate() {
                if cells.contains(&keys.cell(x)) {
                    assert!(covered.contains(&(v as u32)), "grid {k}: vertex {v}");
                    beyond_suspects += usize::from(!culling.is_suspect(v as u32));
                }
            }
        }
        nearby.clear();
        assert!(nearby.vertices().is_empty());
        Some(beyond_suspects)
    }

    /// Cells three springs wide, so a cell holds vertices of patches around a suspect one.
    fn config() -> SelfCollision {
        SelfCollision {
            distance: f64::from(0.5 * SPACING),
            cell_size: f64::from(3.0 * SPACING),
            grids: 4,
            window: 4,
        }
    }

    /// On a sheet folding onto itself: every vertex that shares a cell of any grid with a
    /// suspect, or with a point one of them travelled to, is covered.
    #[test]
    fn covers_every_vertex_that_shares_a_cell_with_a_suspect() {
        let steps = 80;
        let adjacency = Adjacency::from_springs((SIDE * SIDE) as usize, &grid_springs(SIDE, SIDE));
        let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(6);
        let (mut culling, mut nearby) = (Culling::default(), Nearby::default());
        let (mut local_steps, mut beyond_suspects) = (0, 0);
        for t in 0..=steps {
            let positions = folding_sheet(SIDE, SPACING, t, steps, &mut rng);
            // As if a pass had pushed a suspect onto the far corner of the sheet.
            let corner = positions[0] + Vec3::splat(0.1 * SPACING);
            let checked = check_cover(
                &positions,
                &adjacency,
                &config(),
                &mut culling,
                &mut nearby,
                |_| corner,
            );
            if let Some(checked) = checked {
                local_steps += 1;
                beyond_suspects += checked;
            }
        }
        assert!(local_steps > 10, "{local_steps} local steps");
        assert!(beyond_suspects > 1000, "{beyond_suspects}");
    }

    /// Lists in parallel alike on any pool: a cover, moves, and a second cover that adds
    /// patches list every covered vertex in order, with the moved positions kept for the
    /// patches covered first and the owner's positions read for the new ones.
    #[test]
    fn lists_alike_on_any_pool_keeping_the_moves_of_earlier_covers() {
        let side = 160;
        let n = (side * side) as usize;
        let adjacency = Adjacency::from_springs(n, &grid_springs(side, side));
        let config = config();
        let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(9);
        let positions = folding_sheet(side, SPACING, 78, 80, &mut rng);
        let lift = Vec3::new(0.0, 0.1 * SPACING, 0.0);
        let list_on = |threads| {
            let pool = crate::selfcollide::pool_of(threads);
            pool.install(|| {
                let (mut culling, mut nearby) = (Culling::default(), Nearby::default());
                let proof = culling.prove(&positions[..], &adjacency, config.distance as f32);
                assert_eq!(proof, Proof::Local);
                nearby.begin(n, culling.patch_count());
                nearby.cover(&culling, &positions[..], config.cell_size as f32);
                let first = nearby.vertices().to_vec();
                let moves: Vec<(u32, Vec3)> = (0..first.len() as u32)
                    .step_by(3)
                    .map(|slot| (slot, lift))
                    .collect();
                nearby.apply(&moves, f32::INFINITY, |_, _| unreachable!());
                // The sheet's far corner, away from the crease's suspects.
                nearby.moved_far(&culling, positions[n - 1], config.cell_size as f32);
                nearby.cover(&culling, &positions[..], config.cell_size as f32);
                let moved: HashSet<u32> = moves
                    .iter()
                    .map(|&(slot, _)| first[slot as usize])
                    .collect();
                let listed = nearby.vertices().to_vec();
                assert!(listed.is_sorted_by(|a, b| a < b));
                assert!(first.len() > 32 * PATCH, "{} first", first.len());
                assert!(
                    listed.len() > first.len() + PATCH,
                    "{} listed",
                    listed.len()
                );
                let listed_set: HashSet<u32> = listed.iter().copied().collect();
                assert!(first.iter().all(|v| listed_set.contains(v)));
                // The travels carried to the new slots, and every moved vertex a mover.
                let movers: HashSet<u32> = nearby
                    .movers()
                    .iter()
                    .map(|&slot| listed[slot as usize])
                    .collect();
                assert_eq!(movers, moved);
                for (&v, &x) in listed.iter().zip(nearby.positions()) {
                    let expected =
                        positions[v as usize] + if moved.contains(&v) { lift } else { Vec3::ZERO };
                    assert_eq!(x, expected, "vertex {v}");
                    assert_eq!(nearby.position(v), x);
                }
                let listing = (
                    listed.clone(),
                    nearby.positions().to_vec(),
                    nearby.suspects().to_vec(),
                );
                // Each travel is kept at its vertex's new slot: one moved before widens when
                // moved once more, one that did not, does not.
                let slot_of = |v: u32| listed.iter().position(|&w| w == v).unwrap() as u32;
                let (before, after) = (slot_of(first[0]), slot_of(first[1]));
                let mut widened = Vec::new();
                let limit = 1.5 * lift.length();
                nearby.apply(&[(before, lift), (after, lift)], limit, |x, _| {
                    widened.push(x)
                });
                assert_eq!(widened, [positions[first[0] as usize] + lift + lift]);
                listing
            })
        };
        let one = list_on(1);
        assert_eq!(one, list_on(4));
    }

    /// Two flat sheets two springs apart (further than the distance and the margin, closer
    /// than a cell), one vertex of the lower one pushed close to another: the upper sheet's
    /// vertices above the suspects share their cells but lie in patches whose boxes are
    /// apart from the suspects' ones, and must be covered.
    #[test]
    fn covers_a_layer_within_a_cell_of_the_suspects() {
        let one = grid_springs(SIDE, SIDE);
        let n = SIDE * SIDE;
        let ends: Vec<[u32; 2]> = one
            .iter()
            .copied()
            .chain(one.iter().map(|&[a, b]| [a + n, b + n]))
            .collect();
        let adjacency = Adjacency::from_springs(2 * n as usize, &ends);
        let mut positions: Vec<Vec3> = (0..2 * n)
            .map(|v| {
                let (x, z) = ((v % SIDE) as f32, ((v % n) / SIDE) as f32);
                let y = if v < n { 0.0 } else { 2.0 };
                Vec3::new(x, y, z) * SPACING
            })
            .collect();
        // Vertex (20, 20) onto the one diagonally across from it that no spring joins.
        let (a, b) = (20 * SIDE + 20, 21 * SIDE + 19);
        positions[a as usize] = positions[b as usize] + Vec3::new(0.3 * SPACING, 0.0, 0.0);
        let (mut culling, mut nearby) = (Culling::default(), Nearby::default());
        let beyond = check_cover(
            &positions,
            &adjacency,
            &config(),
            &mut culling,
            &mut nearby,
            |_| Vec3::new(5.0, 2.0, 5.0) * SPACING,
        );
        let beyond = beyond.expect("a local proof");
        assert!(culling.is_suspect(a) && !culling.is_suspect(a + n));
        assert!(beyond > 100, "{beyond}");
    }
}
