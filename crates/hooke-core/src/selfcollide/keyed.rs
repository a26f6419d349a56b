//! What a local pass sorts: only the nearby vertices that share a key with a suspect.
//!
//! A local pass tests the suspects' windows, and a window holds only vertices of its own key
//! (see `window_of`). The vertices of the suspects' keys, sorted on their own, come in the
//! same order as they do in a sort of every nearby vertex (the others only fall between
//! runs of keys), so each suspect's run of its key, and so its window and its moves, are the
//! same. At 512^2 in contact they are about a third of the nearby vertices.

use glam::Vec3;

use super::GridKeys;
use super::binning::{Binning, Entry, entry};
use super::wide::wide;

/// Every nearby vertex's key in one grid, by slot, and the set of the suspects' keys.
#[derive(Debug, Default)]
pub(super) struct Keyed {
    pub keys: Vec<u32>,
    pub set: KeySet,
}

impl Keyed {
    /// Keys `positions` (the nearby vertices', by slot) by `grid`, and takes the keys of the
    /// slots that `suspects` marks.
    pub fn key(&mut self, positions: &[Vec3], suspects: &[bool], grid: &GridKeys) {
        self.keys.resize(positions.len(), 0);
        // Compiled with AVX2 where there is one: the hash multiplies 32-bit integers.
        wide(
            #[inline(always)]
            || grid.batch(positions, &mut self.keys),
        );
        self.set.clear();
        for (&key, &suspect) in self.keys.iter().zip(suspects) {
            if suspect {
                self.set.insert(key);
            }
        }
    }

    /// Pushes the entry of every slot whose key is in the set, in slot order.
    ///
    /// Without a branch per slot: at 512^2 in contact the set takes about a third of the
    /// slots, at no pattern a branch predictor could learn. The four grids' sorts ahead of a
    /// step's passes took 85 and 137 us a step this way, against 104 and 190 with a branch,
    /// on alternate steps of two runs (see the performance log, 2026-12-06, twentieth).
    pub fn entries(&self, out: &mut Vec<Entry>) {
        let set = self.set.bits();
        let start = out.len();
        out.resize(start + self.keys.len(), 0);
        // A slice, not the vector: its address and length stay in registers through the stores.
        let room = &mut out[start..];
        let mut count = 0;
        for (&key, slot) in self.keys.iter().zip(0u32..) {
            room[count] = entry(key, slot);
            count += usize::from(set.contains(key));
        }
        out.truncate(start + count);
    }
}

/// The nearby vertices (`positions`, by slot) that share grid `keys`' key with a suspect
/// (`suspects`, by slot), in sorted order; `keyed` keeps their keys.
pub(super) fn sorted_with_suspects<'a>(
    binning: &'a mut Binning,
    keyed: &mut Keyed,
    positions: &[Vec3],
    suspects: &[bool],
    keys: &GridKeys,
) -> &'a [Entry] {
    keyed.key(positions, suspects, keys);
    binning.sort_entries(keys.bits, |out| keyed.entries(out))
}

/// Keys as a bit each of a table indexed by their low [`KEY_SET_BITS`] bits: a set that says
/// it holds every key added, and may say so of other keys that share those bits.
#[derive(Debug)]
pub(super) struct KeySet {
    words: Box<Words>,
}

/// Low bits of a key that index a [`KeySet`]: 8 KiB of bits, in the first-level cache.
const KEY_SET_BITS: u32 = 16;

/// A [`KeySet`]'s table: a fixed size, so that indexing it by a key's low bits needs no check.
type Words = [u64; 1 << (KEY_SET_BITS - 6)];

impl Default for KeySet {
    fn default() -> Self {
        Self {
            words: Box::new([0; 1 << (KEY_SET_BITS - 6)]),
        }
    }
}

/// A [`KeySet`]'s table borrowed for a loop over many keys, which then keeps its address in
/// a register instead of reading it through the set at every key.
#[derive(Clone, Copy)]
pub(super) struct KeyBits<'a>(&'a Words);

impl KeyBits<'_> {
    #[inline(always)]
    pub fn contains(self, key: u32) -> bool {
        let (word, bit) = KeySet::bit(key);
        self.0[word] & bit != 0
    }
}

impl KeySet {
    /// Empties the set.
    pub fn clear(&mut self) {
        self.words.fill(0);
    }

    #[inline(always)]
    fn bit(key: u32) -> (usize, u64) {
        let low = key & ((1 << KEY_SET_BITS) - 1);
        ((low >> 6) as usize, 1 << (low & 63))
    }

    /// Adds `key`; true if the set did not hold it.
    pub fn insert(&mut self, key: u32) -> bool {
        let (word, bit) = Self::bit(key);
        let new = self.words[word] & bit == 0;
        self.words[word] |= bit;
        new
    }

    /// Takes `key` out, with every key that shares its low bits.
    pub fn remove(&mut self, key: u32) {
        let (word, bit) = Self::bit(key);
        self.words[word] &= !bit;
    }

    #[inline(always)]
    pub fn contains(&self, key: u32) -> bool {
        self.bits().contains(key)
    }

    /// The table, for a loop over many keys.
    #[inline(always)]
    pub fn bits(&self) -> KeyBits<'_> {
        KeyBits(&self.words)
    }
}

#[cfg(test)]
pub(super) mod tests {
    use std::collections::HashSet;

    use rand::{RngExt, SeedableRng};
    use rand_chacha::ChaCha8Rng;

    use super::super::binning::key_of;
    use super::super::{SelfCollision, sorted_for_grid};
    use super::*;

    #[test]
    fn a_key_set_holds_what_was_added() {
        let mut set = KeySet::default();
        assert!(set.insert(7) && set.insert(70_000) && !set.insert(7));
        assert!(set.contains(7) && set.contains(70_000) && !set.contains(8));
        // Keys alike in their low 16 bits share a bit.
        assert!(set.contains(7 + (1 << 16)));
        set.remove(7);
        assert!(!set.contains(7) && set.contains(70_000));
        set.clear();
        assert!(!set.contains(70_000));
    }

    /// Cells 1 cm wide, of 4 grids, for [`cloud`].
    pub(in crate::selfcollide) const CELLS: SelfCollision = SelfCollision {
        distance: 0.005,
        cell_size: 0.01,
        grids: 4,
        window: 4,
    };

    /// `n` points at random in a cube `extent` wide (a few points a cell of [`CELLS`], so that
    /// many keys repeat), each a suspect with chance `suspects`; and the generator, seeded
    /// with `seed`.
    pub(in crate::selfcollide) fn cloud(
        seed: u64,
        n: usize,
        extent: f32,
        suspects: f64,
    ) -> (ChaCha8Rng, Vec<Vec3>, Vec<bool>) {
        let mut rng = ChaCha8Rng::seed_from_u64(seed);
        let positions = (0..n)
            .map(|_| Vec3::new(rng.random(), rng.random(), rng.random()) * extent)
            .collect();
        let flags = (0..n).map(|_| rng.random_bool(suspects)).collect();
        (rng, positions, flags)
    }

    /// The sort of the vertices that share a key with a suspect is the sort of all of them
    /// less other keys' runs: the same run of every suspect's key, in the same order.
    #[test]
    fn the_suspects_keys_sort_as_in_a_sort_of_all() {
        let (config, n) = (CELLS, 4000);
        let (_, positions, suspects) = cloud(17, n, 0.12, 0.1);
        for bits in [8, 16, 24] {
            for k in 0..config.grids {
                let keys = GridKeys::with_bits(bits, &config, k);
                let all = sorted_for_grid(&mut Binning::default(), &positions, &keys).to_vec();
                let mut keyed = Keyed::default();
                let some = sorted_with_suspects(
                    &mut Binning::default(),
                    &mut keyed,
                    &positions,
                    &suspects,
                    &keys,
                )
                .to_vec();
                assert!(some.len() < all.len(), "{bits} bits, grid {k}");
                let in_all: HashSet<Entry> = all.iter().copied().collect();
                assert!(some.iter().all(|e| in_all.contains(e)));
                let suspect_keys: HashSet<u32> = (0..n)
                    .filter(|&v| suspects[v])
                    .map(|v| keys.of(positions[v]))
                    .collect();
                let of_suspects = |entries: &[Entry]| -> Vec<Entry> {
                    let keep = |e: &&Entry| suspect_keys.contains(&key_of(**e));
                    entries.iter().filter(keep).copied().collect()
                };
                assert_eq!(
                    of_suspects(&some),
                    of_suspects(&all),
                    "{bits} bits, grid {k}"
                );
                assert!(some.is_sorted());
            }
        }
    }
}
