//! Where a step's self-collision spends its time, part by part: what `hooke bench` prints
//! beside its collision phase, so that a figure says what limits it.

use std::time::{Duration, Instant};

/// One step's self-collision, part by part, wall clock on the calling thread (a part's
/// parallel passes count once, however many threads run them).
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct PartTimes {
    /// The culling's proof (see [`super::Culling::prove`]), in two parts: measuring every
    /// patch of vertices, then the pairs of patches (near pairs from their cached gaps or
    /// measured again, far pairs searched) and listing the suspects. Both zero on a step run
    /// without a proof.
    pub measuring: Duration,
    pub pairs: Duration,
    /// Listing the vertices that local passes sort (the suspects and those that may share a
    /// cell with one), or copying every position for full passes.
    pub covering: Duration,
    /// Sorting by each grid's keys: ahead of the passes, repaired, or anew.
    pub sorting: Duration,
    /// Testing the windows of sorted order, which finds the moves.
    pub window_tests: Duration,
    /// Applying the moves to the passes' positions and counting how far vertices travel; a
    /// solver adds the time it takes to write them back.
    pub moving: Duration,
}

/// A part's clock that reads the time only while parts are timed: a read costs about 30 ns on
/// the development VM and a step makes some 40, which steps nobody times need not pay (about
/// 1% of a 128^2 step with self-collision).
#[derive(Clone, Copy, Debug)]
pub struct Stopwatch(Option<Instant>);

impl Stopwatch {
    pub fn start(on: bool) -> Self {
        Self(on.then(Instant::now))
    }

    /// The time since the start or the last lap, starting the next lap (zero when off).
    pub fn lap(&mut self) -> Duration {
        match &mut self.0 {
            Some(last) => {
                let now = Instant::now();
                let lap = now - *last;
                *last = now;
                lap
            }
            None => Duration::ZERO,
        }
    }
}

impl PartTimes {
    pub fn proof(&self) -> Duration {
        self.measuring + self.pairs
    }

    pub fn total(&self) -> Duration {
        self.proof() + self.covering + self.sorting + self.window_tests + self.moving
    }
}
