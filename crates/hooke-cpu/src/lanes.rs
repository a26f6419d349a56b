//! Per-vertex (or per-spring) quantities with `N` components, stored as `N` runs of 8-lane
//! blocks in one allocation.
//!
//! Each run starts at a different cache-line offset modulo 4 KiB (a global counter staggers
//! them). A vertex pass walks a dozen such runs in lockstep (positions, next positions, deltas
//! and forces, 3 axes each, plus 2 integration constants). With sizes that are multiples of
//! 4 KiB, separately allocated runs all start at the same page offset, map to the same cache
//! sets and evict each other: the same step then ran 3 to 10 times slower depending on where
//! the allocator had put each array.

use std::sync::atomic::{AtomicUsize, Ordering};

use crate::layout::LANES;
use crate::simd::Block;

/// Bytes over which the first-level cache's sets repeat on current x86 and ARM cores: runs
/// read in lockstep that start a multiple of this apart compete for the same sets.
pub(crate) const L1_SET_SPAN: usize = 4096;

/// Bytes per cache line.
pub(crate) const CACHE_LINE: usize = 64;

/// Blocks per [`L1_SET_SPAN`].
const BLOCKS_PER_PAGE: usize = L1_SET_SPAN / std::mem::size_of::<Block>();

/// The next run's offset in cache lines (2 blocks) within a page.
static NEXT_STAGGER: AtomicUsize = AtomicUsize::new(0);

#[derive(Clone, Debug)]
pub struct Lanes<const N: usize> {
    data: Vec<Block>,
    start: [usize; N],
    blocks: usize,
}

/// Three axes: positions, deltas, forces.
pub type Soa = Lanes<3>;

impl<const N: usize> Default for Lanes<N> {
    fn default() -> Self {
        Self::zeros(0)
    }
}

impl<const N: usize> Lanes<N> {
    pub fn zeros(blocks: usize) -> Self {
        let mut start = [0usize; N];
        let mut cursor = 0usize;
        for s in &mut start {
            let line = NEXT_STAGGER.fetch_add(1, Ordering::Relaxed) % (BLOCKS_PER_PAGE / 2);
            let wanted = 2 * line;
            *s = cursor + (wanted + BLOCKS_PER_PAGE - cursor % BLOCKS_PER_PAGE) % BLOCKS_PER_PAGE;
            cursor = *s + blocks;
        }
        Self {
            data: vec![[0.0; LANES]; cursor],
            start,
            blocks,
        }
    }

    /// Copies per-axis block vectors, which must all have the same length.
    pub fn from_axes(axes: [Vec<Block>; N]) -> Self {
        let mut lanes = Self::zeros(axes[0].len());
        for (target, source) in lanes.axes_mut().into_iter().zip(&axes) {
            target.copy_from_slice(source);
        }
        lanes
    }

    pub fn blocks(&self) -> usize {
        self.blocks
    }

    pub fn axis(&self, k: usize) -> &[Block] {
        &self.data[self.start[k]..self.start[k] + self.blocks]
    }

    pub fn axes(&self) -> [&[Block]; N] {
        std::array::from_fn(|k| self.axis(k))
    }

    pub fn axes_mut(&mut self) -> [&mut [Block]; N] {
        let mut rest: &mut [Block] = &mut self.data;
        let mut consumed = 0usize;
        let mut out: [&mut [Block]; N] = std::array::from_fn(|_| <&mut [Block]>::default());
        for (k, slot) in out.iter_mut().enumerate() {
            let (_, tail) = std::mem::take(&mut rest).split_at_mut(self.start[k] - consumed);
            let (axis, tail) = tail.split_at_mut(self.blocks);
            *slot = axis;
            rest = tail;
            consumed = self.start[k] + self.blocks;
        }
        out
    }

    pub fn get(&self, index: usize) -> [f32; N] {
        std::array::from_fn(|k| self.axis(k)[index / LANES][index % LANES])
    }

    /// Writes one vector's entries, each straight into its axis' block: splitting the buffer
    /// into its axes (`axes_mut`) for every call made a write-back of self-collision's
    /// moves take twice as long.
    pub fn set(&mut self, index: usize, value: [f32; N]) {
        for (k, v) in value.into_iter().enumerate() {
            self.data[self.start[k] + index / LANES][index % LANES] = v;
        }
    }

    /// Bytes of payload (the stagger padding is not counted: it is never touched).
    pub fn bytes(&self) -> usize {
        N * self.blocks * std::mem::size_of::<Block>()
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn runs_start_on_distinct_cache_lines_within_a_page() {
        let a = Soa::zeros(BLOCKS_PER_PAGE * 3);
        let b = Soa::zeros(BLOCKS_PER_PAGE * 3);
        let mut offsets: Vec<usize> = a
            .start
            .iter()
            .chain(&b.start)
            .map(|s| s % BLOCKS_PER_PAGE)
            .collect();
        offsets.sort_unstable();
        offsets.dedup();
        assert_eq!(offsets.len(), 6);
    }

    #[test]
    fn axes_are_disjoint_and_round_trip() {
        let mut lanes = Lanes::<2>::zeros(5);
        lanes.set(17, [1.0, 2.0]);
        assert_eq!(lanes.get(17), [1.0, 2.0]);
        let [first, second] = lanes.axes_mut();
        first[0][0] = 3.0;
        second[0][0] = 4.0;
        assert_eq!(lanes.get(0), [3.0, 4.0]);
        assert_eq!(lanes.axis(0).len(), 5);
    }
}
