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
//! Each sort holds only the vertices that share a key with a suspect (see `keyed`). A suspect
//! that moves to a key no suspect had, or a vertex made suspect since (by a widening) whose key
//! none had, brings that key's vertices into the order with it.
//!
//! The order is the one a sort from scratch gives, but for the runs of keys that only a
//! suspect's earlier place had (no window looks at them): an entry is its key above its slot,
//! and a stable sort of slots by key puts the entries in ascending order, which the repair
//! keeps. So the windows, and the moves, are the same.

use glam::Vec3;
use rayon::prelude::*;

use super::GridKeys;
use super::binning::{Binning, Entry, entry};
use super::keyed::{KeySet, Keyed, sorted_with_suspects};

/// The grids' orders of one step's nearby vertices, kept by the resolver so a step allocates
/// nothing.
#[derive(Debug, Default)]
pub(super) struct Ahead {
    /// Grid `k`'s sort in `binnings[k]`: of the vertices that share a key with a suspect
    /// (see `keyed`), whose keys `keyed[k]` keeps.
    binnings: Vec<Binning>,
    keyed: Vec<Keyed>,
    /// How many vertices the sorts were made for, and how many had been made suspects since
    /// they were listed.
    count: usize,
    flagged: usize,
    /// Whether the sorts are this step's (cleared when it ends). Within a step, the nearby
    /// vertices are listed again (renumbering their slots) only when a covering adds
    /// patches, which adds vertices: a count unlike the sorted one says so.
    valid: bool,
    /// A repaired order, and the entries it takes out and puts in.
    repaired: Vec<Entry>,
    taken: Vec<Entry>,
    put: Vec<Entry>,
    /// The slots moved since the sorts, each once with its key now, and a flag per slot.
    moved: Vec<(u32, u32)>,
    is_moved: Vec<bool>,
    /// Keys that suspects have come to since the sorts and no suspect had then.
    added: Vec<u32>,
    added_set: KeySet,
}

impl Ahead {
    /// Sorts the nearby vertices (`positions`, by slot) that share a key with a suspect
    /// (`suspects`; `flagged`, the slots made suspects since the vertices were listed) by the
    /// keys of every one of `grids` grids at once (grid `k`'s: `keys(k)`), a grid a task.
    pub fn sort_all(
        &mut self,
        positions: &[Vec3],
        (suspects, flagged): (&[bool], &[u32]),
        grids: u32,
        keys: impl Fn(u32) -> GridKeys + Sync,
    ) {
        self.binnings.resize_with(grids as usize, Binning::default);
        self.keyed.resize_with(grids as usize, Keyed::default);
        self.binnings
            .par_iter_mut()
            .zip(&mut self.keyed)
            .zip(0..grids)
            .for_each(|((binning, keyed), k)| {
                sorted_with_suspects(binning, keyed, positions, suspects, &keys(k));
            });
        self.count = positions.len();
        self.flagged = flagged.len();
        self.valid = true;
    }

    /// Forgets the sorts: the step is over.
    pub fn clear(&mut self) {
        self.valid = false;
    }

    /// Grid `k`'s order by `keys` (grid `k`'s, as sorted) of the nearby vertices at
    /// `positions` that share a key with a suspect (`suspects`, and `flagged` as given to
    /// [`Ahead::sort_all`] and added to since), those at `moved` (slots, in any order,
    /// repeats allowed) moved since the sorts. `None` if the sorts do not hold these
    /// vertices.
    pub fn order(
        &mut self,
        k: usize,
        positions: &[Vec3],
        (suspects, flagged): (&[bool], &[u32]),
        moved: impl Iterator<Item = u32>,
        keys: &GridKeys,
    ) -> Option<&[Entry]> {
        if !self.valid || positions.len() != self.count || k >= self.binnings.len() {
            return None;
        }
        let Self {
            keyed,
            moved: moved_now,
            is_moved,
            added,
            added_set,
            taken,
            put,
            ..
        } = self;
        let keyed = &mut keyed[k];
        is_moved.resize(positions.len(), false);
        moved_now.clear();
        for slot in moved {
            if !is_moved[slot as usize] {
                is_moved[slot as usize] = true;
                moved_now.push((slot, keys.of(positions[slot as usize])));
            }
        }
        // A suspect that has moved to a key no suspect had, or a vertex made suspect since
        // (by a widening) whose key none had: the key's vertices join the order.
        added.clear();
        let mut add = |set: &mut KeySet, key: u32| {
            if set.insert(key) {
                added_set.insert(key);
                added.push(key);
            }
        };
        for &(slot, now) in moved_now.iter() {
            if suspects[slot as usize] {
                add(&mut keyed.set, now);
            }
        }
        for &slot in flagged.get(self.flagged..).unwrap_or_default() {
            if !is_moved[slot as usize] {
                add(&mut keyed.set, keyed.keys[slot as usize]);
            }
        }
        taken.clear();
        put.clear();
        for &(slot, now) in moved_now.iter() {
            let then = keyed.keys[slot as usize];
            let was = keyed.set.contains(then) && !added_set.contains(then);
            let is = keyed.set.contains(now);
            if was && is && then == now {
                continue;
            }
            if was {
                taken.push(entry(then, slot));
            }
            if is {
                put.push(entry(now, slot));
            }
        }
        // The other vertices of the keys added (7-15 keys an order at 512^2 in contact), in
        // one scan whose test is mostly a bit of a 256-bit mask held in registers rather than
        // a load from `added_set`'s table for every vertex.
        if !added.is_empty() {
            let mut mask = [0u64; 4];
            for &key in added.iter() {
                mask[(key >> 6 & 3) as usize] |= 1 << (key & 63);
            }
            for (slot, &key) in (0u32..).zip(&keyed.keys) {
                if mask[(key >> 6 & 3) as usize] >> (key & 63) & 1 != 0
                    && added_set.contains(key)
                    && !is_moved[slot as usize]
                {
                    put.push(entry(key, slot));
                }
            }
        }
        for &(slot, _) in moved_now.iter() {
            is_moved[slot as usize] = false;
        }
        for &key in added.iter() {
            added_set.remove(key);
        }
        let sorted = self.binnings[k].sorted();
        if self.taken.is_empty() && self.put.is_empty() {
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
        Some(&self.repaired)
    }
}

#[cfg(test)]
mod tests {
    use std::collections::HashSet;

    use rand::RngExt;

    use super::super::binning::{key_of, vertex_of};
    use super::super::key_bits;
    use super::super::keyed::tests::{CELLS, cloud};
    use super::*;

    #[test]
    fn a_repaired_order_is_the_sort_of_the_moved_positions() {
        let (config, n) = (CELLS, 5000);
        let (mut rng, start, start_suspects) = cloud(11, n, 0.15, 0.2);
        // 8 bits: keys of far cells alike, and sets that hold other keys than the suspects'.
        for bits in [8, key_bits(n), 24] {
            let keys: Vec<GridKeys> = (0..config.grids)
                .map(|k| GridKeys::with_bits(bits, &config, k))
                .collect();
            let mut ahead = Ahead::default();
            let mut flagged = Vec::new();
            ahead.sort_all(&start, (&start_suspects, &flagged), config.grids, |k| {
                GridKeys::with_bits(bits, &config, k)
            });
            let (mut positions, mut suspects) = (start.clone(), start_suspects.clone());
            let mut moved = Vec::new();
            for (k, keys) in keys.iter().enumerate() {
                let expected = sorted_with_suspects(
                    &mut Binning::default(),
                    &mut Keyed::default(),
                    &positions,
                    &suspects,
                    keys,
                )
                .to_vec();
                let order = ahead
                    .order(
                        k,
                        &positions,
                        (&suspects, &flagged),
                        moved.iter().copied(),
                        keys,
                    )
                    .expect("sorted")
                    .to_vec();
                // In order, each slot once with its key now; the runs of keys that only
                // suspects' earlier places had may be left in (no window looks at them).
                assert!(order.is_sorted(), "grid {k}, {bits} bits");
                let slots: HashSet<u32> = order.iter().map(|&e| vertex_of(e)).collect();
                assert_eq!(slots.len(), order.len());
                assert!(
                    order
                        .iter()
                        .all(|&e| keys.of(positions[vertex_of(e) as usize]) == key_of(e))
                );
                let suspect_keys: HashSet<u32> = (0..n)
                    .filter(|&s| suspects[s])
                    .map(|s| keys.of(positions[s]))
                    .collect();
                // (A set of keys by their low 16 bits also takes keys alike in those.)
                let of_suspects = |entries: Vec<Entry>| -> Vec<Entry> {
                    let keep = |e: &Entry| suspect_keys.contains(&key_of(*e));
                    entries.into_iter().filter(keep).collect()
                };
                assert_eq!(
                    of_suspects(order),
                    of_suspects(expected),
                    "grid {k}, {bits} bits"
                );
                // Some suspects moved by up to a cell (some of them twice), a few other
                // vertices too, and some made suspects (as a widening does).
                for _ in 0..200 {
                    let slot = if rng.random_bool(0.9) {
                        let suspect: Vec<u32> =
                            (0..n as u32).filter(|&s| suspects[s as usize]).collect();
                        suspect[rng.random_range(0..suspect.len())]
                    } else {
                        rng.random_range(0..n as u32)
                    };
                    let push = Vec3::new(rng.random(), rng.random(), rng.random()) - 0.5;
                    positions[slot as usize] += push * 0.02;
                    moved.push(slot);
                }
                for _ in 0..50 {
                    let slot = rng.random_range(0..n);
                    if !suspects[slot] {
                        suspects[slot] = true;
                        flagged.push(slot as u32);
                    }
                }
            }
            // Other vertices than those sorted: no order.
            let fewer = &positions[1..];
            let fewer_suspects = (&suspects[1..], &flagged[..]);
            let order = ahead.order(1, fewer, fewer_suspects, moved.iter().copied(), &keys[1]);
            assert_eq!(order, None);
            ahead.clear();
            let suspects = (&suspects[..], &flagged[..]);
            let order = ahead.order(1, &positions, suspects, moved.iter().copied(), &keys[1]);
            assert_eq!(order, None);
        }
    }
}
