//! Keeping the pool's other threads awake through a run of short parallel passes.
//!
//! A rayon worker that finds no work for a few microseconds goes to sleep, and waking it again
//! costs the next parallel pass far more than the pass itself when the pass is short. On the
//! project's 2-vCPU Intel VM (2026-11-27, rayon 1.12) a pass of two 10 us tasks took 12 us
//! when the worker had been idle for 5 us, and 24-39 us after 20-500 us; kept awake, 12-13 us
//! after any pause. A self-collision step is dozens of such passes (the proof's, and each
//! grid's sort and window tests) with serial work between them, and its second thread
//! barely paid for itself.

use std::sync::atomic::{AtomicBool, Ordering};

/// Work that the pool's other threads take up between the parallel passes they are kept
/// awake for: small pieces, each run whole by one thread, so that a pass handed out meanwhile
/// waits at most one piece for them.
pub trait Idle: Sync {
    /// Runs one piece if one is ready; false if none is.
    fn run_one(&self) -> bool;
}

/// Nothing to take up.
pub struct NoIdle;

impl Idle for NoIdle {
    fn run_one(&self) -> bool {
        false
    }
}

/// Runs `work` on the current thread while every other thread of the current pool stays
/// awake, running whatever parallel work `work` hands out, else a piece of `idle`, and
/// spinning in between. Returns `work`'s result; the other threads go back to the pool when it
/// returns, each once its piece of `idle` is done.
pub fn with_pool_awake<R: Send>(idle: &dyn Idle, work: impl FnOnce() -> R + Send) -> R {
    let others = rayon::current_num_threads().saturating_sub(1);
    if others == 0 {
        return work();
    }
    let done = AtomicBool::new(false);
    rayon::scope(|scope| {
        for _ in 0..others {
            scope.spawn(|_| {
                while !done.load(Ordering::Acquire) {
                    // Run one pending task of the pool if there is one, else a piece of
                    // `idle`, else wait a moment.
                    if rayon::yield_now() != Some(rayon::Yield::Executed) && !idle.run_one() {
                        std::hint::spin_loop();
                    }
                }
            });
        }
        let result = work();
        done.store(true, Ordering::Release);
        result
    })
}

#[cfg(test)]
mod tests {
    use rayon::prelude::*;

    use super::*;

    #[test]
    fn runs_the_work_once_and_its_parallel_passes_in_full_on_any_pool_size() {
        for threads in [1, 2, 4] {
            let pool = crate::selfcollide::pool_of(threads);
            let runs = std::sync::atomic::AtomicUsize::new(0);
            let sums: Vec<u64> = pool.install(|| {
                with_pool_awake(&NoIdle, || {
                    runs.fetch_add(1, Ordering::Relaxed);
                    (0..50u64)
                        .map(|pass| (0..10_000u64).into_par_iter().map(|i| i * pass).sum())
                        .collect()
                })
            });
            assert_eq!(runs.load(Ordering::Relaxed), 1);
            let expected: Vec<u64> = (0..50u64).map(|pass| pass * 9_999 * 10_000 / 2).collect();
            assert_eq!(sums, expected, "{threads} threads");
        }
    }
}
