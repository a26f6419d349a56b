//! The sort inside every self-collision pass: vertices grouped by cell key, stably (vertices
//! of one key stay in index order, which decides every window), on every core.
//!
//! A least-significant-digit radix sort in as few digit passes as the key's bits allow (two
//! for the 24-bit keys of up to 2^23 vertices, of 12 bits each), whose first histogram is
//! counted in the pass that computes the keys. Each pass splits the input into one chunk per
//! thread: a chunk's entries of one digit go after every chunk's entries of smaller digits and
//! after earlier chunks' entries of the same digit, which keeps the sort stable for any number
//! of threads, and gives each chunk output ranges of its own to write. (`radsort`, used before,
//! runs on one thread, and sorting took half of the self-collision time at 512^2.)

use rayon::prelude::*;

use super::disjoint::Disjoint;
use super::wide::wide;

/// A vertex in sorted order: its key in the high 32 bits, its index in the low 32.
pub type Entry = u64;

/// The entry of `vertex` with `key`.
#[inline(always)]
pub fn entry(key: u32, vertex: u32) -> Entry {
    (Entry::from(key) << 32) | Entry::from(vertex)
}

/// The key of a sorted entry.
pub fn key_of(entry: Entry) -> u32 {
    (entry >> 32) as u32
}

/// The vertex of a sorted entry.
pub fn vertex_of(entry: Entry) -> u32 {
    entry as u32
}

/// Entries per counter that a chunk needs before splitting pays: every chunk clears, scans and
/// offsets a whole histogram of the digit, serially in the scan, so a chunk of fewer entries
/// than this many per counter spends more on its histogram than on its entries. (One chunk per
/// thread whatever the size, as before, made a local pass's 10,000-entry sort with 4096
/// counters cost 16 histograms on 16 threads, and the contact step slower than on 8.)
const ENTRIES_PER_COUNTER: usize = 4;

/// Entries a chunk needs before splitting pays at all: a sort's four parallel loops hand
/// the other threads their chunks four times, and a local pass's sort of 4,000-12,000 entries
/// (256 counters) took longer on this project's 2-vCPU Intel VM in two chunks than in one:
/// 0.22-0.23 against 0.10 ms a step's four sorts at 256^2 in contact, 0.45 against 0.35 at
/// 512^2 (2026-11-28, throwaway timers, medians of 12 windows of 100 steps).
const MIN_CHUNK: usize = 16_384;

/// Widest digit: 4096 counters per chunk stay in the first-level cache.
const MAX_DIGIT_BITS: u32 = 12;

/// Keys computed at a time before they are counted: a batch is a plain loop the compiler
/// vectorises, which a key computed and counted per entry is not.
const KEY_BATCH: usize = 256;

/// Buffers kept from one sort to the next, so a step allocates nothing.
#[derive(Debug, Default)]
pub struct Binning {
    entries: Vec<Entry>,
    spare: Vec<Entry>,
    /// One histogram of the current digit per chunk, chunk after chunk.
    counts: Vec<u32>,
}

/// How a sort splits its keys into digits: as few passes as [`MAX_DIGIT_BITS`] allows, of
/// equal width.
#[derive(Clone, Copy)]
struct Digits {
    passes: u32,
    width: u32,
    mask: u32,
}

impl Digits {
    fn of(bits: u32) -> Self {
        let passes = bits.div_ceil(MAX_DIGIT_BITS).max(1);
        let width = bits.div_ceil(passes).max(1);
        Self {
            passes,
            width,
            mask: (1u32 << width) - 1,
        }
    }

    fn buckets(&self) -> usize {
        self.mask as usize + 1
    }
}

/// How a pass cuts `n` entries into chunks.
#[derive(Clone, Copy)]
struct Chunks {
    len: usize,
    count: usize,
}

impl Chunks {
    /// At most one chunk per thread, each of at least [`MIN_CHUNK`] entries and
    /// [`ENTRIES_PER_COUNTER`] entries per one of the digit's `buckets`.
    fn new(n: usize, buckets: usize) -> Self {
        let least = (ENTRIES_PER_COUNTER * buckets).max(MIN_CHUNK);
        let wanted = (n / least).clamp(1, rayon::current_num_threads().max(1));
        let len = n.div_ceil(wanted).max(1);
        Self {
            len,
            count: n.div_ceil(len),
        }
    }
}

impl Binning {
    /// Sorts vertices `0..n` by their keys, every key below `2^bits`, stably; returns the
    /// entries in sorted order. `keys(first, out)` writes the keys of vertices `first..` into
    /// `out`, a batch at a time.
    pub fn sort(
        &mut self,
        n: usize,
        bits: u32,
        keys: impl Fn(usize, &mut [u32]) + Sync,
    ) -> &[Entry] {
        let digits = Digits::of(bits);
        self.entries.resize(n, 0);
        if n == 0 {
            return &self.entries;
        }
        let chunks = self.prepare(n, digits);
        // The keys, and the first digit's histogram, in one pass.
        self.entries
            .par_chunks_mut(chunks.len)
            .zip(self.counts.par_chunks_mut(digits.buckets()))
            .enumerate()
            .for_each(|(c, (entries, counts))| {
                key_chunk(c * chunks.len, &keys, entries, counts, digits.mask);
            });
        self.digit_passes(digits, chunks, true)
    }

    /// Sorts the entries that `fill` pushes (in ascending order of their low 32 bits, every
    /// key below `2^bits`) by key, stably.
    pub fn sort_entries(&mut self, bits: u32, fill: impl FnOnce(&mut Vec<Entry>)) -> &[Entry] {
        let digits = Digits::of(bits);
        self.entries.clear();
        fill(&mut self.entries);
        if self.entries.is_empty() {
            return &self.entries;
        }
        let chunks = self.prepare(self.entries.len(), digits);
        self.digit_passes(digits, chunks, false)
    }

    /// The chunks of a sort of `n` entries, and the buffers sized for them.
    fn prepare(&mut self, n: usize, digits: Digits) -> Chunks {
        let chunks = Chunks::new(n, digits.buckets());
        self.spare.resize(n, 0);
        self.counts.clear();
        self.counts.resize(chunks.count * digits.buckets(), 0);
        chunks
    }

    /// Every digit's pass over the entries; the first digit's histogram is in `counts`
    /// already if `counted`.
    fn digit_passes(&mut self, digits: Digits, chunks: Chunks, counted: bool) -> &[Entry] {
        for pass in 0..digits.passes {
            let shift = pass * digits.width;
            if pass > 0 || !counted {
                count_digits(&self.entries, &mut self.counts, shift, digits.mask, chunks);
            }
            scatter(
                &self.entries,
                &mut self.spare,
                &mut self.counts,
                shift,
                digits.mask,
                chunks,
            );
            std::mem::swap(&mut self.entries, &mut self.spare);
        }
        &self.entries
    }

    /// The entries of the last sort, in sorted order.
    pub fn sorted(&self) -> &[Entry] {
        &self.entries
    }

    /// [`Binning::sort`] of vertices `0..keys.len()` by the keys given.
    pub fn sort_keys(&mut self, keys: &[u32], bits: u32) -> &[Entry] {
        self.sort(keys.len(), bits, |first, out| {
            out.copy_from_slice(&keys[first..first + out.len()]);
        })
    }
}

/// The entries of vertices `first..first + entries.len()`, their keys written by `keys` a
/// batch at a time (see [`KEY_BATCH`]), and their histogram of the first digit (`mask`) into
/// `counts`; compiled for AVX2 where the CPU has it (see [`wide`]: every sort keys all
/// vertices, and `keys` is inlined into the loop).
fn key_chunk(
    first: usize,
    keys: &impl Fn(usize, &mut [u32]),
    entries: &mut [Entry],
    counts: &mut [u32],
    mask: u32,
) {
    wide(
        #[inline(always)]
        move || {
            // Locals, not the closure's captures: a capture is loaded through the closure for
            // every entry, as the compiler cannot tell it apart from the counts being written,
            // and the processor then waits for each count's store before the next load. With
            // such loads in this loop and the two below, a sort on an AMD EPYC VM took about
            // twice as long: 217-235 us against 113-126 for 16,000 entries (a local pass at
            // 512^2), 2.3-2.8 ms against 1.5-1.9 for 262,144 sorted on 24 bits (a full pass).
            let (entries, counts, mask) = (entries, counts, mask);
            let mut batch = [0u32; KEY_BATCH];
            for (b, out) in entries.chunks_mut(KEY_BATCH).enumerate() {
                let start = first + b * KEY_BATCH;
                let batch = &mut batch[..out.len()];
                keys(start, batch);
                for ((slot, &key), v) in out.iter_mut().zip(batch.iter()).zip(start..) {
                    *slot = entry(key, v as u32);
                    counts[digit(key, 0, mask)] += 1;
                }
            }
        },
    );
}

/// The digit of `key` at `shift` that `mask` takes.
#[inline(always)]
fn digit(key: u32, shift: u32, mask: u32) -> usize {
    ((key >> shift) & mask) as usize
}

/// Each chunk's histogram of the digit at `shift`.
fn count_digits(entries: &[Entry], counts: &mut [u32], shift: u32, mask: u32, chunks: Chunks) {
    let buckets = counts.len() / chunks.count;
    counts.fill(0);
    entries
        .par_chunks(chunks.len)
        .zip(counts.par_chunks_mut(buckets))
        .for_each(|(entries, counts)| {
            // Locals, not the closure's captures (see `key_chunk`).
            let (shift, mask) = (shift, mask);
            for &entry in entries {
                counts[digit(key_of(entry), shift, mask)] += 1;
            }
        });
}

/// Moves every entry of `input` to `output` in digit order, stably, each chunk on a thread.
/// `counts` (each chunk's histogram of the digit) becomes each chunk's next slot per digit.
fn scatter(
    input: &[Entry],
    output: &mut [Entry],
    counts: &mut [u32],
    shift: u32,
    mask: u32,
    chunks: Chunks,
) {
    let buckets = counts.len() / chunks.count;
    // Slots digit-major, chunk-minor: a chunk's entries of a digit go after every chunk's
    // smaller digits and the earlier chunks' same digit.
    let mut next = 0u32;
    for d in 0..buckets {
        for c in 0..chunks.count {
            let count = counts[c * buckets + d];
            counts[c * buckets + d] = next;
            next += count;
        }
    }
    let output = Disjoint::new(output);
    input
        .par_chunks(chunks.len)
        .zip(counts.par_chunks_mut(buckets))
        .for_each(|(entries, slots)| {
            // Locals, not the closure's captures (see `key_chunk`).
            let (shift, mask, output) = (shift, mask, output);
            for &entry in entries {
                let slot = &mut slots[digit(key_of(entry), shift, mask)];
                // SAFETY: the slots computed above give every chunk disjoint ranges of
                // `output`, one per digit, each as long as the chunk's count of that digit.
                #[allow(unsafe_code)]
                unsafe {
                    output.write(*slot as usize, entry)
                };
                *slot += 1;
            }
        });
}

#[cfg(test)]
mod tests {
    use super::*;
    use rand::{RngExt, SeedableRng};

    #[test]
    fn equals_a_stable_comparison_sort_for_every_size_and_key_width() {
        let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(3);
        let mut binning = Binning::default();
        // Sizes on both sides of the parallel threshold; few and many repeats; 8 to 32 bits.
        for (n, bits, range) in [
            (0, 8, 1u64 << 8),
            (1, 8, 1 << 8),
            (1000, 8, 7),
            (5000, 16, 1 << 16),
            (MIN_CHUNK * 2 + 17, 16, 300),
            (100_000, 24, 1 << 24),
            (70_001, 24, 5000),
            (40_000, 32, 1 << 32),
        ] {
            let keys: Vec<u32> = (0..n).map(|_| rng.random_range(0..range) as u32).collect();
            let mut expected: Vec<(u32, u32)> = keys.iter().copied().zip(0..).collect();
            expected.sort_by_key(|&(key, _)| key);
            let sorted: Vec<(u32, u32)> = binning
                .sort_keys(&keys, bits)
                .iter()
                .map(|&e| (key_of(e), vertex_of(e)))
                .collect();
            assert_eq!(sorted, expected, "{n} keys of {bits} bits");
        }
    }

    #[test]
    fn sorting_given_entries_equals_a_stable_comparison_sort() {
        let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(5);
        let mut binning = Binning::default();
        for (n, bits, range) in [
            (0, 8, 1u64 << 8),
            (3000, 16, 40),
            (MIN_CHUNK * 3, 24, 1 << 24),
        ] {
            // Every third vertex or so, in ascending order.
            let mut given = Vec::new();
            for v in 0..n as u32 {
                if rng.random_bool(0.3) {
                    given.push(entry(rng.random_range(0..range) as u32, v));
                }
            }
            let mut expected = given.clone();
            expected.sort_by_key(|&e| key_of(e));
            let sorted = binning.sort_entries(bits, |out| out.extend_from_slice(&given));
            assert_eq!(sorted, expected, "{n} vertices, {bits} bits");
        }
    }

    #[test]
    fn any_thread_count_sorts_alike() {
        let keys: Vec<u32> = (0..200_000u32)
            .map(|v| v.wrapping_mul(2_654_435_761) >> 12)
            .collect();
        let sort_on = |threads| {
            let pool = crate::selfcollide::pool_of(threads);
            pool.install(|| Binning::default().sort_keys(&keys, 20).to_vec())
        };
        let one = sort_on(1);
        assert_eq!(one, sort_on(3));
        assert_eq!(one, sort_on(8));
    }
}
