//! The next step's spring forces and integration, begun beside self-collision's passes.
//!
//! Self-collision's local passes (see `hooke_core::selfcollide`) leave the pool's other
//! thread waiting for a third of their time or more: each pass's sorting, covering and moving
//! are short serial runs between short parallel ones. Once the proof has found the step's
//! [`Zone`] (the patches that may hold a vertex the passes move, and those within two springs
//! of them), the next step's force and integration of every slice outside it depends on
//! nothing the passes can change: its vertices and their neighbours stay where the
//! integration put them. The waiting thread runs those slices then, a small piece at a time
//! ([`PIECE`]), so that a pass handed out meanwhile waits at most one piece; the next step
//! runs only the slices left. Same arithmetic per vertex, so the same bits.
//!
//! A scatter mesh that steps block by block (see `blocks`) begins its next step by block
//! ([`EarlyBlocks`]): a block outside the zone has its force rows computed, a run at a time,
//! and its slices are summed and integrated once every row they sum is written. Every row of
//! such a block is final: its springs' first ends lie outside the zone, which holds every
//! vertex within two springs of one the passes may move, so neither end moves. The blocks
//! are taken a band of the step at a time in turn (see `blocks::BlockSteps::block_order`).
//! The next step then computes only the rows left, and sums only the slices left.
//!
//! Only within one `step(n)`, on 2 threads or more, on meshes of [`MIN_SLICES`] or more whose
//! force pass reads the positions by axis (gather, or scatter block by block), and where
//! nothing else acts between the two steps' spring forces: no tearing, external forces,
//! colliders or handles.

use std::ops::Range;
use std::sync::atomic::{AtomicBool, AtomicUsize, Ordering};
use std::sync::{Mutex, OnceLock};

use hooke_core::selfcollide::{Beside, Idle, Zone};

use crate::blocks::{BlockSteps, runs};
use crate::kernels::VertexChunk;
use crate::layout::LANES;
use crate::sweep::Buffers;
use crate::view::Positions;

/// Slices a mesh needs for its steps to begin early: on the bench's 128^2 sheet (2,048
/// slices), whose self-collision takes some 40 us a step in contact, the paired ratio read
/// 2.08 and 2.105 by median with steps begun early against 1.995 and 2.005 without (two
/// batches of runs), and 2.445-2.525 against 2.58-2.67 at 256^2 (8,192 slices).
pub(crate) const MIN_SLICES: usize = 4096;

/// The next step as a sweep's buffers number it (see `sweep::Buffers`): it reads this step's
/// new positions (`next`) and writes its own into `current`.
const NEXT: usize = 2;

/// Slices a piece: about a microsecond of one thread's work at 512^2. Pieces are fixed runs
/// of slices; one that holds a slice of the zone is left to the next step whole.
const PIECE: usize = 32;

/// Runs of a block's force rows that [`EarlyBlocks`] hands out apart, and runs of its slices,
/// kept short so that a pass handed out meanwhile waits little: a block of 1,056 first ends
/// at 512^2 has some 390 rows of 8 springs and 132 slices, so a run is some 49 rows or 16-17
/// slices, less work than gather's piece. (Runs of a quarter and of a sixteenth of a block
/// read alike in throwaway runs: see the performance log, 2026-12-07, twenty-ninth.)
const BLOCK_PARTS: usize = 8;

/// What the next step has done already: its slices in `ranges` (ascending, disjoint), for
/// scatter the blocks whose force rows it wrote (`rows`, a flag per block), and whether all
/// its results were finite.
#[derive(Debug, Default)]
pub(crate) struct Done {
    pub ranges: Vec<Range<usize>>,
    pub rows: Vec<bool>,
    pub finite: bool,
}

/// What either kind of early step keeps while the passes run: the zone until a waiting thread
/// takes it, and what that thread marked of it; the pieces handed out so far (may run past
/// their count); whether every result was finite.
struct Handout<T> {
    zone: Mutex<Option<Zone>>,
    marks: OnceLock<T>,
    taken: AtomicUsize,
    finite: AtomicBool,
    /// Tests: every piece runs as soon as the zone is offered, on the thread that offers it,
    /// so that a test sees pieces run whatever the machine's scheduling leaves the waiting
    /// threads.
    #[cfg(test)]
    eagerly: bool,
}

impl<T> Handout<T> {
    fn new() -> Self {
        Self {
            zone: Mutex::new(None),
            marks: OnceLock::new(),
            taken: AtomicUsize::new(0),
            finite: AtomicBool::new(true),
            #[cfg(test)]
            eagerly: false,
        }
    }

    /// The next piece to run.
    fn next(&self) -> usize {
        self.taken.fetch_add(1, Ordering::Relaxed)
    }

    fn failed(&self) {
        self.finite.store(false, Ordering::Relaxed);
    }

    fn offer(&self, zone: Zone) {
        *self.zone.lock().unwrap_or_else(|e| e.into_inner()) = Some(zone);
    }

    /// What `mark` made of the zone; or, before that, `Err(true)` on the first thread to
    /// find the zone offered, which marks it (its piece of work), and `Err(false)` while it
    /// is not.
    fn marks(&self, mark: impl FnOnce(&Zone) -> T) -> Result<&T, bool> {
        if let Some(marks) = self.marks.get() {
            return Ok(marks);
        }
        let zone = self.zone.try_lock().ok().and_then(|mut zone| zone.take());
        match zone {
            Some(zone) => {
                let _ = self.marks.set(mark(&zone));
                Err(true)
            }
            None => Err(false),
        }
    }
}

/// The next step, offered to self-collision's waiting threads.
pub(crate) struct EarlyStep<'a, K> {
    buffers: &'a Buffers,
    kernel: &'a K,
    slices: usize,
    /// The pieces handed out, and the zone marked as a bit per piece that holds a slice of it.
    handout: Handout<Vec<u64>>,
}

impl<'a, K> EarlyStep<'a, K>
where
    K: Fn(Positions<'_>, VertexChunk<'_>) -> bool + Sync,
{
    /// The next step over `buffers` (`slices` of them), each piece run by `kernel`: it reads
    /// the step's new positions (`next`) and writes the next step's into `current`, and the
    /// deltas.
    pub fn new(buffers: &'a Buffers, kernel: &'a K, slices: usize) -> Self {
        Self {
            buffers,
            kernel,
            slices,
            handout: Handout::new(),
        }
    }

    /// Tests: with `on`, every piece runs as soon as the zone is offered (see `eagerly`).
    #[cfg(test)]
    pub fn eagerly(mut self, on: bool) -> Self {
        self.handout.eagerly = on;
        self
    }

    /// What was done: the pieces handed out that the zone does not touch, every one of them
    /// finished (the waiting threads finish theirs before the passes' call returns).
    pub fn done(self) -> Done {
        let pieces = self.slices.div_ceil(PIECE);
        let taken = self.handout.taken.into_inner().min(pieces);
        let ranges = match self.handout.marks.into_inner() {
            Some(touched) => (0..taken)
                .filter(|&k| !is_set(&touched, k))
                .map(|k| piece(k, self.slices))
                .collect(),
            None => Vec::new(),
        };
        Done {
            ranges,
            rows: Vec::new(),
            finite: self.handout.finite.into_inner(),
        }
    }

    /// A bit per piece that holds a slice of `zone`.
    fn touched_by(&self, zone: &Zone) -> Vec<u64> {
        let mut touched = vec![0u64; self.slices.div_ceil(PIECE).div_ceil(64)];
        zone.each_place(|place| {
            let k = place as usize / LANES / PIECE;
            touched[k / 64] |= 1 << (k % 64);
        });
        touched
    }
}

/// Whether bit `k` of `bits` is set.
fn is_set(bits: &[u64], k: usize) -> bool {
    bits[k / 64] >> (k % 64) & 1 != 0
}

/// The slices of piece `k`.
fn piece(k: usize, slices: usize) -> Range<usize> {
    k * PIECE..((k + 1) * PIECE).min(slices)
}

impl<K> Idle for EarlyStep<'_, K>
where
    K: Fn(Positions<'_>, VertexChunk<'_>) -> bool + Sync,
{
    fn run_one(&self) -> bool {
        let touched = match self.handout.marks(|zone| self.touched_by(zone)) {
            Ok(touched) => touched,
            Err(marked) => return marked,
        };
        let pieces = self.slices.div_ceil(PIECE);
        loop {
            let k = self.handout.next();
            if k >= pieces {
                return false;
            }
            if is_set(touched, k) {
                continue;
            }
            // SAFETY: step 2 of the buffers reads `next` and writes `current` and the deltas.
            // Every piece is handed out once, and pieces do not overlap; while the passes run
            // nothing else writes `next` (self-collision writes its moves back after them) or
            // touches `current` or the deltas, and the piece lies outside the zone, so
            // nothing it reads moves in this step.
            let finite = unsafe {
                self.buffers
                    .step(NEXT, piece(k, self.slices), true, self.kernel)
            };
            if !finite {
                self.handout.failed();
            }
            return true;
        }
    }
}

impl<K> Beside for EarlyStep<'_, K>
where
    K: Fn(Positions<'_>, VertexChunk<'_>) -> bool + Sync,
{
    fn offer(&self, zone: Zone) {
        self.handout.offer(zone);
        #[cfg(test)]
        if self.handout.eagerly {
            while self.run_one() {}
        }
    }
}

/// A scatter mesh's next step, by block, offered to self-collision's waiting threads (see the
/// module docs). Each block is [`BLOCK_PARTS`] runs of its force rows and as many of its
/// slices, handed out in that order, block after block in [`BlockSteps::block_order`].
pub(crate) struct EarlyBlocks<'a> {
    step: BlockSteps<'a>,
    /// The blocks in the order they are handed out (see [`BlockSteps::block_order`]).
    order: Vec<usize>,
    /// The pieces handed out, and the zone marked as a flag per block that holds a slice of it.
    handout: Handout<Vec<bool>>,
    /// Per block, its runs of rows not yet written.
    rows_left: Vec<AtomicUsize>,
    /// The runs of slices summed and integrated, in no order.
    slices_done: Mutex<Vec<Range<usize>>>,
}

impl<'a> EarlyBlocks<'a> {
    pub fn new(step: BlockSteps<'a>) -> Self {
        let blocks = step.block_count();
        Self {
            order: step.block_order(),
            step,
            handout: Handout::new(),
            rows_left: (0..blocks).map(|_| AtomicUsize::new(BLOCK_PARTS)).collect(),
            slices_done: Mutex::new(Vec::new()),
        }
    }

    /// Tests: with `on`, every piece runs as soon as the zone is offered.
    #[cfg(test)]
    pub fn eagerly(mut self, on: bool) -> Self {
        self.handout.eagerly = on;
        self
    }

    /// What was done (the waiting threads finish their pieces before the passes' call
    /// returns).
    pub fn done(self) -> Done {
        let rows = self
            .rows_left
            .into_iter()
            .map(|left| left.into_inner() == 0)
            .collect();
        let mut ranges = self
            .slices_done
            .into_inner()
            .unwrap_or_else(|e| e.into_inner());
        ranges.sort_unstable_by_key(|range| range.start);
        Done {
            ranges,
            rows,
            finite: self.handout.finite.into_inner(),
        }
    }

    /// A flag per block that holds a slice of `zone`.
    fn touched_by(&self, zone: &Zone) -> Vec<bool> {
        let mut touched = vec![false; self.step.block_count()];
        zone.each_place(|place| touched[BlockSteps::block_of(place as usize / LANES)] = true);
        touched
    }

    /// Whether every force row that `slice` sums is written.
    fn summable(&self, slice: usize, touched: &[bool]) -> bool {
        self.step
            .summed_blocks(slice)
            .all(|k| !touched[k] && self.rows_left[k].load(Ordering::Acquire) == 0)
    }
}

impl Idle for EarlyBlocks<'_> {
    fn run_one(&self) -> bool {
        let touched = match self.handout.marks(|zone| self.touched_by(zone)) {
            Ok(touched) => touched,
            Err(marked) => return marked,
        };
        let pieces = self.step.block_count() * 2 * BLOCK_PARTS;
        loop {
            let t = self.handout.next();
            if t >= pieces {
                return false;
            }
            let (k, part) = (self.order[t / (2 * BLOCK_PARTS)], t % (2 * BLOCK_PARTS));
            if touched[k] {
                continue;
            }
            if part < BLOCK_PARTS {
                // SAFETY: each run of rows is handed out once, and nothing else touches the
                // forces while the passes run; the block lies outside the zone, so no end of
                // its springs moves in this step.
                unsafe { self.step.rows(NEXT, run(self.step.rows_of(k), part)) };
                self.rows_left[k].fetch_sub(1, Ordering::Release);
                return true;
            }
            let slices = run(self.step.slices_of(k), part - BLOCK_PARTS);
            let summable = |s: &usize| self.summable(*s, touched);
            for run in runs(slices, summable) {
                // SAFETY: the rows these slices sum are written (`summable`) and no thread
                // writes them again; each run of slices is handed out once; they lie outside
                // the zone, so nothing they read moves in this step.
                if !unsafe { self.step.slices(NEXT, run.clone()) } {
                    self.handout.failed();
                }
                let mut done = self.slices_done.lock().unwrap_or_else(|e| e.into_inner());
                done.push(run);
            }
            return true;
        }
    }
}

impl Beside for EarlyBlocks<'_> {
    fn offer(&self, zone: Zone) {
        self.handout.offer(zone);
        #[cfg(test)]
        if self.handout.eagerly {
            while self.run_one() {}
        }
    }
}

/// Run `part` of [`BLOCK_PARTS`] of `range`.
fn run(range: Range<usize>, part: usize) -> Range<usize> {
    let at = |p: usize| range.start + range.len() * p / BLOCK_PARTS;
    at(part)..at(part + 1)
}

/// The runs of `0..slices` outside `done` (ascending, disjoint), cut into runs of at most
/// `most`.
pub(crate) fn left_over(done: &[Range<usize>], slices: usize, most: usize) -> Vec<Range<usize>> {
    let mut left = Vec::new();
    let mut cut = |start: usize, end: usize| {
        let mut first = start;
        while first < end {
            let last = (first + most).min(end);
            left.push(first..last);
            first = last;
        }
    };
    let mut from = 0;
    for range in done {
        cut(from, range.start);
        from = range.end;
    }
    cut(from, slices);
    left
}

#[cfg(test)]
mod tests {
    use hooke_core::Solver;
    use hooke_core::scene::MeshSection;
    use hooke_core::selfcollide::SelfCollision;
    use hooke_testkit::{benchmark_scene, state_of};

    use super::*;
    use crate::{CpuSolver, Method};

    /// On the bench's sheet in contact with itself (after 1,500 steps), steps begun beside
    /// self-collision's passes give the states of single steps, which begin none: with the
    /// pieces run as the zone is offered (so that some surely run), and with them left to the
    /// waiting threads. Gather on a 192^2 sheet; scatter on a 256^2 one, the smallest grid
    /// that steps block by block.
    #[test]
    fn steps_begun_beside_self_collision_give_the_states_of_single_steps() {
        for (method, side) in [(Method::Gather, 192), (Method::Scatter, 256)] {
            steps_begun_early_give_the_states_of_single_steps(method, side);
        }
    }

    fn steps_begun_early_give_the_states_of_single_steps(method: Method, side: u32) {
        let mut scene = benchmark_scene(MeshSection::unit_grid(side, side), side * side);
        scene.model.collision.self_collision = Some(SelfCollision::for_model(&scene.model));
        let mut settler = CpuSolver::for_test(&scene, method, 2);
        settler.step(1500).expect("stable");
        let settled = state_of(&settler);
        for (threads, eagerly) in [(2, true), (3, true), (2, false), (3, false)] {
            let what = format!("{method:?}, {threads} threads, eagerly: {eagerly}");
            let mut single = CpuSolver::for_test(&scene, method, threads);
            let mut begun = CpuSolver::for_test(&scene, method, threads);
            assert!(begun.numbering.slice_count() >= MIN_SLICES);
            begun.early_eagerly = eagerly;
            single.write_state(&settled);
            begun.write_state(&settled);
            let (steps, mut slices, mut blocks) = (20, 0, 0);
            let pool = std::sync::Arc::clone(&begun.pool);
            assert!(pool.install(|| begun.can_step_early()), "{what}");
            for k in 0..steps {
                single.step(1).expect("stable");
                pool.install(|| begun.step_once(None, k + 1 < steps))
                    .expect("stable");
                if let Some(done) = &begun.early {
                    slices += done.ranges.iter().map(Range::len).sum::<usize>();
                    blocks += done.rows.iter().filter(|&&written| written).count();
                }
            }
            assert!(begun.early.is_none());
            assert!(state_of(&single) == state_of(&begun), "{what}");
            // Vertices must have moved, and slices run early, or the comparison says
            // nothing.
            assert!(begun.self_collider.local_passes() > 0, "{what}");
            let all = begun.numbering.slice_count() * steps;
            assert!(slices < all, "{what}");
            assert!(slices > 0 || !eagerly, "{what}: no slice begun early");
            // Scatter's slices begun early sum rows written early.
            let scatter = method == Method::Scatter;
            assert!(
                blocks > 0 || !eagerly || !scatter,
                "{what}: no rows written early"
            );
        }
    }

    #[test]
    fn what_is_left_over_covers_the_rest_once_in_runs_of_at_most_the_given_length() {
        let done = [2..5, 5..6, 9..10];
        let left = left_over(&done, 14, 3);
        assert_eq!(left, vec![0..2, 6..9, 10..13, 13..14]);
        assert_eq!(left_over(&[], 4, 3), vec![0..3, 3..4]);
        assert!(left_over(&[0..2, 2..4], 4, 3).is_empty());
    }
}
