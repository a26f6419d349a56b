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
//! Only within one `step(n)`, on 2 threads or more, on gather meshes of [`MIN_SLICES`] or
//! more whose force pass reads the positions by axis, and where nothing else acts between
//! the two steps' spring forces: no tearing, external forces, colliders or handles.

use std::ops::Range;
use std::sync::atomic::{AtomicBool, AtomicUsize, Ordering};
use std::sync::{Mutex, OnceLock};

use hooke_core::selfcollide::{Beside, Idle, Zone};

use crate::kernels::VertexChunk;
use crate::layout::LANES;
use crate::sweep::Buffers;
use crate::view::Positions;

/// Slices a mesh needs for its steps to begin early: on the bench's 128^2 sheet (2,048
/// slices), whose self-collision takes some 40 us a step in contact, the paired ratio read
/// 2.08 and 2.105 by median with steps begun early against 1.995 and 2.005 without (two
/// batches of runs), and 2.445-2.525 against 2.58-2.67 at 256^2 (8,192 slices).
pub(crate) const MIN_SLICES: usize = 4096;

/// Slices a piece: about a microsecond of one thread's work at 512^2. Pieces are fixed runs
/// of slices; one that holds a slice of the zone is left to the next step whole.
const PIECE: usize = 32;

/// What the next step has done already: its slices in `ranges` (ascending, disjoint), and
/// whether all their results were finite.
#[derive(Debug, Default)]
pub(crate) struct Done {
    pub ranges: Vec<Range<usize>>,
    pub finite: bool,
}

/// The next step, offered to self-collision's waiting threads.
pub(crate) struct EarlyStep<'a, K> {
    buffers: &'a Buffers,
    kernel: &'a K,
    slices: usize,
    /// The zone, until a waiting thread takes it to mark the pieces it touches.
    zone: Mutex<Option<Zone>>,
    /// A bit per piece that holds a slice of the zone.
    touched: OnceLock<Vec<u64>>,
    /// Pieces handed out so far, those touched among them (may run past their count).
    taken: AtomicUsize,
    finite: AtomicBool,
    /// Tests: every piece runs as soon as the zone is offered, on the thread that offers it,
    /// so that a test sees pieces run whatever the machine's scheduling leaves the waiting
    /// threads.
    #[cfg(test)]
    eagerly: bool,
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
            zone: Mutex::new(None),
            touched: OnceLock::new(),
            taken: AtomicUsize::new(0),
            finite: AtomicBool::new(true),
            #[cfg(test)]
            eagerly: false,
        }
    }

    /// Tests: with `on`, every piece runs as soon as the zone is offered (see `eagerly`).
    #[cfg(test)]
    pub fn eagerly(self, on: bool) -> Self {
        Self {
            eagerly: on,
            ..self
        }
    }

    /// What was done: the pieces handed out that the zone does not touch, every one of them
    /// finished (the waiting threads finish theirs before the passes' call returns).
    pub fn done(self) -> Done {
        let pieces = self.slices.div_ceil(PIECE);
        let taken = self.taken.into_inner().min(pieces);
        let ranges = match self.touched.into_inner() {
            Some(touched) => (0..taken)
                .filter(|&k| !is_set(&touched, k))
                .map(|k| piece(k, self.slices))
                .collect(),
            None => Vec::new(),
        };
        Done {
            ranges,
            finite: self.finite.into_inner(),
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
        let Some(touched) = self.touched.get() else {
            // The first thread to find the zone offered marks the pieces it touches.
            let zone = self.zone.try_lock().ok().and_then(|mut zone| zone.take());
            return match zone {
                Some(zone) => {
                    let _ = self.touched.set(self.touched_by(&zone));
                    true
                }
                None => false,
            };
        };
        let pieces = self.slices.div_ceil(PIECE);
        loop {
            let k = self.taken.fetch_add(1, Ordering::Relaxed);
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
                    .step(2, piece(k, self.slices), true, self.kernel)
            };
            if !finite {
                self.finite.store(false, Ordering::Relaxed);
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
        *self.zone.lock().unwrap_or_else(|e| e.into_inner()) = Some(zone);
        #[cfg(test)]
        if self.eagerly {
            while self.run_one() {}
        }
    }
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

    /// On the bench's 192^2 sheet in contact with itself (after 1,500 steps), steps begun
    /// beside self-collision's passes give the states of single steps, which begin none:
    /// with the pieces run as the zone is offered (so that some surely run), and with them
    /// left to the waiting threads.
    #[test]
    fn steps_begun_beside_self_collision_give_the_states_of_single_steps() {
        let mut scene = benchmark_scene(MeshSection::unit_grid(192, 192), 192 * 192);
        scene.model.collision.self_collision = Some(SelfCollision::for_model(&scene.model));
        let mut settler = CpuSolver::for_test(&scene, Method::Gather, 2);
        settler.step(1500).expect("stable");
        let settled = state_of(&settler);
        for (threads, eagerly) in [(2, true), (3, true), (2, false), (3, false)] {
            let what = format!("{threads} threads, eagerly: {eagerly}");
            let mut single = CpuSolver::for_test(&scene, Method::Gather, threads);
            let mut begun = CpuSolver::for_test(&scene, Method::Gather, threads);
            assert!(begun.numbering.slice_count() >= MIN_SLICES);
            begun.early_eagerly = eagerly;
            single.write_state(&settled);
            begun.write_state(&settled);
            let (steps, mut slices) = (20, 0);
            let pool = std::sync::Arc::clone(&begun.pool);
            for k in 0..steps {
                single.step(1).expect("stable");
                pool.install(|| begun.step_once(None, k + 1 < steps))
                    .expect("stable");
                slices += begun
                    .early
                    .as_ref()
                    .map_or(0, |done| done.ranges.iter().map(Range::len).sum::<usize>());
            }
            assert!(begun.early.is_none());
            assert!(state_of(&single) == state_of(&begun), "{what}");
            // Vertices must have moved, and slices run early, or the comparison says
            // nothing.
            assert!(begun.self_collider.local_passes() > 0, "{what}");
            let all = begun.numbering.slice_count() * steps;
            assert!(slices < all, "{what}");
            assert!(slices > 0 || !eagerly, "{what}: no slice begun early");
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
