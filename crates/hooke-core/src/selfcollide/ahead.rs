//! Every grid's sort of a step's local passes, made at once before the first pass and repaired
//! before each later one.
//!
//! A local pass sorts a few thousand vertices on one thread (the sort is too short to split),
//! one grid after another, while the pool's other threads wait. Grid `k`'s keys depend on the
//! positions after the passes before it, but those move few vertices (a few hundred a pass at
//! 512^2 in contact), and fewer still change their key in a later grid (0-16). So all grids are
//! sorted side by side from the positions the first pass starts from, one grid a task, and a
//! later pass takes its grid's order with the entries of the vertices whose key has changed
//! since taken out and put back where their new keys go.
//!
//! The order is the one a sort from scratch gives: an entry is its key above its slot, and a
//! stable sort of slots `0..n` by key puts the entries in ascending order, which the repair
//! keeps. So the windows, and the moves, are the same.

use glam::Vec3;
use rayon::prelude::*;

use super::GridKeys;
use super::binning::{Binning, Entry, entry, key_of, vertex_of};

/// The grids' orders of one step's nearby vertices, kept by the resolver so a step allocates
/// nothing.
#[derive(Debug, Default)]
pub(super) struct Ahead {
    /// Grid `k`'s sort in `binnings[k]`.
    binnings: Vec<Binning>,
    /// The positions the sorts were keyed from, by slot.
    positions: Vec<Vec3>,
    /// Whether the sorts are this step's (cleared when it ends). Within a step, the nearby
    /// vertices are listed again (renumbering their slots) only when a covering adds
    /// patches, which adds vertices: a count unlike the sorted positions' says so.
    valid: bool,
    /// A repaired order, and the entries it takes out and puts in.
    repaired: Vec<Entry>,
    taken: Vec<Entry>,
    put: Vec<Entry>,
}

impl Ahead {
    /// Sorts `positions` (the nearby vertices', by slot) by the keys of every one of `grids`
    /// grids at once (grid `k`'s: `keys(k)`), a grid a task.
    pub fn sort_all(
        &mut self,
        positions: &[Vec3],
        grids: u32,
        keys: impl Fn(u32) -> GridKeys + Sync,
    ) {
        self.binnings.resize_with(grids as usize, Binning::default);
        self.binnings
            .par_iter_mut()
            .zip(0..grids)
            .for_each(|(binning, k)| {
                super::sorted_for_grid(binning, positions, &keys(k));
            });
        self.positions.clear();
        self.positions.extend_from_slice(positions);
        self.valid = true;
    }

    /// Forgets the sorts: the step is over.
    pub fn clear(&mut self) {
        self.valid = false;
    }

    /// Grid `k`'s order of `positions` by `keys` (grid `k`'s, as sorted): the positions sorted,
    /// those at `moved` (slots, in any order, repeats allowed) moved since. `None` if the
    /// sorts do not hold these vertices.
    pub fn order(
        &mut self,
        k: usize,
        positions: &[Vec3],
        moved: impl Iterator<Item = u32>,
        keys: &GridKeys,
    ) -> Option<&[Entry]> {
        if !self.valid || positions.len() != self.positions.len() || k >= self.binnings.len() {
            return None;
        }
        self.taken.clear();
        self.put.clear();
        for slot in moved {
            let (then, now) = (
                keys.of(self.positions[slot as usize]),
                keys.of(positions[slot as usize]),
            );
            if then != now {
                self.taken.push(entry(then, slot));
                self.put.push(entry(now, slot));
            }
        }
        let sorted = self.binnings[k].sorted();
        if self.taken.is_empty() {
            return Some(sorted);
        }
        for list in [&mut self.taken, &mut self.put] {
            list.sort_unstable();
            list.dedup();
        }
        // The runs between the entries taken and where those put go, copied whole.
        self.repaired.clear();
        let (mut from, mut put) = (0, self.put.iter().peekable());
        for &gone in &self.taken {
            let at = sorted.partition_point(|&e| e < gone);
            while let Some(&p) = put.next_if(|&&p| p < gone) {
                let before = sorted.partition_point(|&e| e < p);
                self.repaired.extend_from_slice(&sorted[from..before]);
                self.repaired.push(p);
                from = before;
            }
            self.repaired.extend_from_slice(&sorted[from..at]);
            from = at + 1;
        }
        for &p in put {
            let before = sorted.partition_point(|&e| e < p);
            self.repaired.extend_from_slice(&sorted[from..before]);
            self.repaired.push(p);
            from = before;
        }
        self.repaired.extend_from_slice(&sorted[from..]);
        debug_assert!(self.repaired.is_sorted());
        debug_assert!(
            self.repaired
                .iter()
                .all(|&e| keys.of(positions[vertex_of(e) as usize]) == key_of(e))
        );
        Some(&self.repaired)
    }
}

#[cfg(test)]
mod tests {
    use rand::{RngExt, SeedableRng};

    use super::super::{SelfCollision, key_bits, sorted_for_grid};
    use super::*;

    #[test]
    fn a_repaired_order_is_the_sort_of_the_moved_positions() {
        let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(11);
        let config = SelfCollision {
            distance: 0.005,
            cell_size: 0.01,
            grids: 4,
            window: 4,
        };
        // Cells of a few points each, so that many keys repeat.
        let n = 5000;
        let start: Vec<Vec3> = (0..n)
            .map(|_| Vec3::new(rng.random(), rng.random(), rng.random()) * 0.15)
            .collect();
        for bits in [8, key_bits(n)] {
            let keys: Vec<GridKeys> = (0..config.grids)
                .map(|k| GridKeys::with_bits(bits, &config, k))
                .collect();
            let mut ahead = Ahead::default();
            ahead.sort_all(&start, config.grids, |k| {
                GridKeys::with_bits(bits, &config, k)
            });
            let mut positions = start.clone();
            let mut moved = Vec::new();
            for (k, keys) in keys.iter().enumerate() {
                let expected = sorted_for_grid(&mut Binning::default(), &positions, keys).to_vec();
                let order = ahead.order(k, &positions, moved.iter().copied(), keys);
                assert_eq!(order, Some(&expected[..]), "grid {k}, {bits} bits");
                // Some points moved by up to a cell, some of them twice.
                for _ in 0..200 {
                    let slot = rng.random_range(0..n as u32);
                    let push = Vec3::new(rng.random(), rng.random(), rng.random()) - 0.5;
                    positions[slot as usize] += push * 0.02;
                    moved.push(slot);
                }
            }
            // Other vertices than those sorted: no order.
            let fewer = &positions[1..];
            assert_eq!(ahead.order(1, fewer, moved.iter().copied(), &keys[1]), None);
            ahead.clear();
            assert_eq!(
                ahead.order(1, &positions, moved.iter().copied(), &keys[1]),
                None
            );
        }
    }
}
