//! Scatter's force pass and accumulation block by block, for meshes larger than the caches.
//!
//! A scatter step writes a force per spring, then reads each back where it sums the forces at
//! the vertices; on a mesh whose forces leave the caches, the second pass reads them all from
//! memory again. The springs are ordered by blocks of [`SPRING_BLOCK`] first ends (see
//! `tables::spring_order`), and every spring a vertex sums is owned by a vertex of its own block
//! or of a lower one (`owned_rows` re-owns springs only within a block), so once the spring rows
//! of the blocks up to `k` are computed, the vertices of block `k` can be summed and integrated
//! while those forces are still in the cache.
//!
//! The blocks are cut into bands, one task each. A task computes its blocks' rows in order and
//! after each block integrates the block's slices whose springs all lie in rows of its own band
//! (a block's rows are those from its first spring's row, rounded up, to the next block's, so
//! a row shared by two blocks belongs to the first). The other slices, the first of a band
//! whose lower neighbours' springs lie in the band before, wait for a second pass, once every
//! band's rows are written. Each task writes only its band's rows of forces and its band's
//! slices, and in the first pass reads only rows its own band has written: the tasks touch
//! disjoint memory. Every vertex sums the same forces in the same order as in the plain step,
//! so the states are bit-identical (tested).
//!
//! **Several steps per sweep.** Where nothing acts between one step's forces and the next (see
//! `sweep`), [`Blocks::sweep`] advances the blocks several steps while they are in the cache,
//! as the gather's sweep does with slices (as many steps as its rule gives, but 4 at most on
//! narrow bands: see [`BlockSweep::plan`]). A block's rows reach at most `r` blocks past
//! it (its springs' ends), so the slices of block `k` sum rows of blocks `k - r..=k`. Step `j`
//! of a sweep (1-based) computes its rows from the positions of step `j - 1` and integrates
//! from them into the buffer of step `j - 2`. Each band's steps lean into the band above, as
//! the gather's do: band `k`'s slices of step `j` cover `[s_k + (j-1) r, s_{k+1} + (j-1) r)`
//! (`s_k` its lower boundary, moved down to even out the bands' work), and its rows start a
//! reach lower, where its slices of step `j - 1` start, so its slices sum only its own rows and
//! its rows read positions of its own slices (or the sweep's first; at the mesh's ends rows and
//! slices start and end together). Within the band, step `j` trails step `j - 1` by `r` blocks:
//! the positions its rows read are then final, and no slice of step `j - 1` still sums the rows
//! it overwrites. Past its top boundary a band then finishes each step, rows once the band
//! above has done its slices of step `j - 1` a reach past them (whose positions they read, and
//! whose rows of step `j - 1` they overwrite), slices once that band has done its rows of step
//! `j` up to them. Bands are taken from the top down, and a band does its lowest blocks without
//! waiting, so the band waited for is always running and soon there. An earlier schedule
//! stopped each band's steps short of its ends and ran the strips left at each boundary in a
//! second pass, one thread per boundary (see the performance log). Every vertex sums the same
//! forces in the same order: the states are bit-identical (tested).

use std::ops::Range;

use rayon::prelude::*;

use crate::kernels::{
    self, Block, ForceRows, ForcesView, IncidenceTable, InstructionSet, Integrator, Point, Soa,
    SpringForces, SpringTable, VertexChunk,
};
use crate::layout::LANES;
use crate::ring::ForceRing;
use crate::sweep::{self, Buffers, Finite, Progress};
use crate::tables::SPRING_BLOCK;
use crate::view::{Floats, Points, Positions};

/// Slices a mesh needs at least for blocks to pay: 65,536 vertices. Below that, a step's
/// forces stay in the caches anyway. On an Intel Xeon VM with 2 MiB of L2 a core, the
/// irregular bench mesh of 65,536 vertices, swept over blocks of 1,024 first ends, took
/// 0.278-0.317 ms a scatter step against 0.295-0.365 plainly (see the performance log); with blocks
/// of 4,096 it fitted one band only and did not sweep, and blocks alone did not pay.
const MIN_SLICES: usize = 8_192;

/// Bands per thread, so a thread that finishes early takes another.
const BANDS_PER_THREAD: usize = 4;

/// Slices per block of first ends.
const BLOCK_SLICES: usize = SPRING_BLOCK as usize / LANES;

/// How a scatter mesh's step runs block by block (see the module docs).
#[derive(Clone, Debug, PartialEq, Eq)]
pub(crate) struct Blocks {
    /// Per block, its first spring row; one more entry ends the last block's rows.
    rows: Vec<usize>,
    /// Per slice, the first block whose rows hold a spring it sums.
    first_block: Vec<u32>,
    /// Per band, its first block; one more entry ends the last band.
    bands: Vec<usize>,
    /// How several steps sweep the blocks, when they may (see [`Blocks::sweep`]).
    sweep: Option<BlockSweep>,
}

/// Blocks a band holds at least for its sweeps to go past [`NARROW_BAND_DEPTH`] steps. Where
/// bands are narrower, the work a band does near its boundaries, which grows with the steps
/// per sweep, weighs more: on an AMD EPYC VM the irregular bench mesh of 65,536 vertices (two
/// bands of 31 blocks) took 0.195-0.196 ms a scatter step sweeping 6 steps against
/// 0.192-0.195 at 4 (four runs each), while the irregular mesh of 262,144 (two bands of 124)
/// took 1.08-1.11 ms at 6 against 1.17-1.23 at 4 (see the performance log).
const WIDE_BAND: usize = 64;

/// Steps per sweep at most on bands narrower than [`WIDE_BAND`] blocks.
const NARROW_BAND_DEPTH: usize = 4;

/// Several steps per sweep over the blocks: the furthest block, past its own, that a
/// block's rows reach (so also the furthest before its own that a slice's sums reach), and
/// the bands of the sweep, first block each, one more entry ending the last.
#[derive(Clone, Debug, PartialEq, Eq)]
struct BlockSweep {
    reach: usize,
    bands: Vec<usize>,
    /// Steps per sweep at most (2..=[`sweep::DEPTH`]).
    depth: usize,
}

impl Blocks {
    /// The blocks of a scatter mesh of `slices` slices with `springs` springs stepped by
    /// `threads` threads, or `None` where they would not pay: too small a mesh, or too few
    /// blocks for a band per thread.
    pub(crate) fn plan(
        springs: &SpringTable,
        incidence: &IncidenceTable,
        slices: usize,
        threads: usize,
    ) -> Option<Self> {
        let spring_count = springs.slots;
        if slices < MIN_SLICES {
            return None;
        }
        let blocks = slices.div_ceil(BLOCK_SLICES);
        let band_count = (threads * BANDS_PER_THREAD).min(blocks / 2);
        if band_count < 2 {
            return None;
        }
        // A block's first spring: the springs are ordered by their first end's block.
        let mut first_slot = vec![spring_count; blocks + 1];
        let firsts = (0..springs.a.len()).flat_map(|row| springs.a.row(row));
        for (slot, a) in firsts.take(spring_count).enumerate() {
            let block = &mut first_slot[a as usize / SPRING_BLOCK as usize];
            *block = (*block).min(slot);
        }
        // Blocks without springs start where the next one does.
        for k in (0..blocks).rev() {
            first_slot[k] = first_slot[k].min(first_slot[k + 1]);
        }
        let rows: Vec<usize> = first_slot.iter().map(|s| s.div_ceil(LANES)).collect();
        let spring_rows = spring_count.div_ceil(LANES);
        let block_of_row = |row: usize| rows.partition_point(|&start| start <= row) - 1;
        let first_block = (0..slices)
            .map(|slice| {
                incidence
                    .slices
                    .rows(slice)
                    .flat_map(|row| incidence.entry.row(row))
                    .map(|entry| (entry & !kernels::B_END) as usize / LANES)
                    // Padding entries read the zero row past the springs'.
                    .filter(|&row| row < spring_rows)
                    .map(block_of_row)
                    .min()
                    .unwrap_or(slice / BLOCK_SLICES) as u32
            })
            .collect();
        let bands = (0..=band_count).map(|b| b * blocks / band_count).collect();
        let sweep = BlockSweep::plan(springs, &rows, spring_count, threads);
        Some(Self {
            rows,
            first_block,
            bands,
            sweep,
        })
    }

    /// Steps per sweep at most, where the blocks sweep.
    pub(crate) fn sweep_depth(&self) -> Option<usize> {
        self.sweep.as_ref().map(|plan| plan.depth)
    }

    fn band_count(&self) -> usize {
        self.bands.len() - 1
    }

    /// The slices of blocks `blocks`.
    fn slices(&self, blocks: Range<usize>) -> Range<usize> {
        let slices = self.first_block.len();
        (blocks.start * BLOCK_SLICES).min(slices)..(blocks.end * BLOCK_SLICES).min(slices)
    }

    /// One scatter step, block by block: every spring's force into `spring_forces`, and every
    /// vertex summed and integrated into `out`, but for what `begun` says ran beside the last
    /// step's self-collision (see `crate::early`). True if every new position is finite.
    #[allow(clippy::too_many_arguments)] // the plain step's inputs, passed on to its kernels
    pub(crate) fn step(
        &self,
        isa: InstructionSet,
        springs: &SpringTable,
        incidence: &IncidenceTable,
        spring_forces: &mut SpringForces,
        integrator: &Integrator,
        current: &Soa,
        points: Option<&[Point]>,
        extra: Option<&Soa>,
        out: Outputs,
        begun: &Begun,
    ) -> bool {
        let forces = Forces::new(spring_forces);
        // SAFETY: tasks read only rows that no task writes meanwhile (the module docs).
        let view = unsafe { forces.view() };
        let positions = Positions::new(current, None);
        let integrate = |slices: Range<usize>| {
            // SAFETY: the schedule of the module docs: no other task touches these slices.
            let chunk = unsafe { out.chunk(slices) };
            kernels::accumulate_and_integrate(
                isa, incidence, view, integrator, positions, extra, chunk,
            )
        };
        let first = (0..self.band_count()).into_par_iter().map(|b| {
            let band = self.bands[b]..self.bands[b + 1];
            let mut finite = true;
            for k in band.clone() {
                if !begun.rows(k) {
                    // SAFETY: block k's rows belong to this band alone, and no task reads them
                    // before this one has written them (the module docs).
                    let rows = unsafe { forces.rows(self.rows[k]..self.rows[k + 1]) };
                    let positions = Positions::new(current, points);
                    kernels::spring_forces(isa, springs, positions, self.rows[k], rows);
                }
                let ready =
                    |s: &usize| self.first_block[*s] as usize >= band.start && !begun.slice(*s);
                finite &=
                    runs(self.slices(k..k + 1), ready).fold(true, |all, r| integrate(r) & all);
            }
            finite
        });
        let first = first.reduce(|| true, |a, b| a && b);
        let second = (0..self.band_count()).into_par_iter().map(|b| {
            let band = self.bands[b]..self.bands[b + 1];
            let waiting =
                |s: &usize| (self.first_block[*s] as usize) < band.start && !begun.slice(*s);
            runs(self.slices(band.clone()), waiting).fold(true, |all, r| integrate(r) & all)
        });
        first & second.reduce(|| true, |a, b| a && b)
    }
}

impl Blocks {
    /// `depth` steps (2 up to the plan's depth) in one sweep over the blocks, a band per task
    /// (see the module docs). Per step, whether every new position was finite.
    #[allow(clippy::too_many_arguments)] // a step's inputs, passed on to its kernels
    pub(crate) fn sweep(
        &self,
        depth: usize,
        isa: InstructionSet,
        tables: (&SpringTable, &IncidenceTable),
        spring_forces: &mut SpringForces,
        ring: Option<&ForceRing>,
        integrator: &Integrator,
        buffers: &Buffers,
    ) -> Finite {
        let plan = self.sweep.as_ref().expect("a sweep plan");
        let blocks = self.rows.len() - 1;
        let forces = Forces::for_sweep(spring_forces, ring);
        self.with_work(isa, tables, forces, integrator, buffers, |work| {
            plan.run(depth, blocks, work)
        })
    }

    /// A buffer for the spring forces of this plan's sweeps (see `ring`): pages repeating a
    /// ring in each band's interior, where no other band reads or writes, of as many bytes as
    /// a band's steps have forces in use at once. `None` where the plan does not sweep or the
    /// system cannot map it.
    pub(crate) fn force_ring(&self, spring_forces: &SpringForces) -> Option<ForceRing> {
        let plan = self.sweep.as_ref()?;
        let (arrays, row_bytes, rows) = match spring_forces {
            SpringForces::Axes(axes) => (3, std::mem::size_of::<Block>(), axes.blocks()),
            SpringForces::Points(points) => {
                (1, std::mem::size_of::<[Point; LANES]>(), points.len())
            }
        };
        let (r, blocks, bands) = (plan.reach, self.rows.len() - 1, plan.bands.len() - 1);
        let depth = plan.depth;
        // Around a boundary b, both bands touch blocks [R(b, 1), S(b, depth)) of any sweep of
        // up to `depth` steps (see `BlockSweep::slice_line`); these zones keep pages of their
        // own.
        let zone =
            |b: usize| b.saturating_sub((depth + 1) * r + 1)..(b + depth * r + 1).min(blocks);
        let interiors: Vec<Range<usize>> = (0..bands)
            .map(|k| {
                let start = if k == 0 { 0 } else { zone(plan.bands[k]).end };
                let end = if k + 1 == bands {
                    blocks
                } else {
                    zone(plan.bands[k + 1]).start
                };
                let rows = self.rows[start.min(end)]..self.rows[end];
                rows.start * row_bytes..rows.end * row_bytes
            })
            .collect();
        // The rows a band has in use at once span at most `depth` reaches of blocks and the
        // block being written: step j's from a reach below its slices' front to its rows'
        // front, which trails step j - 1's by a reach (see `BlockSweep::run_band`).
        let widest = self.rows.windows(2).map(|w| w[1] - w[0]).max().unwrap_or(0);
        let ring_bytes = (depth * r + 1) * widest * row_bytes;
        ForceRing::new(arrays, rows * row_bytes, &interiors, ring_bytes)
    }

    /// `f` of the work of a sweep's steps over `buffers` (see [`Work`]).
    fn with_work<R>(
        &self,
        isa: InstructionSet,
        (springs, incidence): (&SpringTable, &IncidenceTable),
        forces: Forces,
        integrator: &Integrator,
        buffers: &Buffers,
        f: impl FnOnce(&Work<'_>) -> R,
    ) -> R {
        let steps = BlockSteps::new(self, isa, springs, incidence, forces, integrator, buffers);
        let work = Work {
            // SAFETY: the schedule of the module docs: these rows and the positions they read
            // are this task's alone while it runs.
            rows: &|j: usize, blocks: Range<usize>| unsafe {
                steps.rows(j, self.rows[blocks.start]..self.rows[blocks.end]);
            },
            // SAFETY: as for the rows.
            slices: &|j: usize, blocks: Range<usize>| unsafe {
                steps.slices(j, self.slices(blocks))
            },
        };
        f(&work)
    }
}

/// What a band of a sweep over the blocks does, step `j` (1-based) over blocks `blocks`: its
/// rows, from the positions of step `j - 1`, and its slices, summed and integrated (true if
/// every new position is finite).
struct Work<'a> {
    rows: &'a (dyn Fn(usize, Range<usize>) + Sync),
    slices: &'a (dyn Fn(usize, Range<usize>) -> bool + Sync),
}

/// How far a band's rows and its slices have got, step by step.
#[derive(Default)]
struct BandProgress {
    rows: Progress,
    slices: Progress,
}

/// Where one band's steps have got: per step (1-based), the block below which its rows are
/// done, and below which its slices are.
struct Front<'a> {
    rows: [usize; sweep::DEPTH + 1],
    slices: [usize; sweep::DEPTH + 1],
    finite: Finite,
    work: &'a Work<'a>,
    progress: &'a BandProgress,
}

impl Front<'_> {
    /// Step `j`'s rows up to block `end`.
    fn rows_to(&mut self, j: usize, end: usize) {
        if end > self.rows[j] {
            (self.work.rows)(j, self.rows[j]..end);
            self.rows[j] = end;
            self.progress.rows.publish(j, end);
        }
    }

    /// Step `j`'s slices up to block `end`.
    fn slices_to(&mut self, j: usize, end: usize) {
        if end > self.slices[j] {
            self.finite[j] &= (self.work.slices)(j, self.slices[j]..end);
            self.slices[j] = end;
            self.progress.slices.publish(j, end);
        }
    }
}

impl BlockSweep {
    /// Where band `k`'s slices of step `j` of a sweep of `depth` steps start, so where band
    /// `k - 1`'s end: boundary `k`, moved down by half a reach for each of the `depth - 1`
    /// steps (which gives every band the same block-steps), plus `j - 1` reaches.
    fn slice_line(&self, k: usize, j: usize, depth: usize) -> usize {
        let last = self.bands.len() - 1;
        if k == 0 || k == last {
            return self.bands[k];
        }
        self.bands[k] - (depth - 1) * self.reach / 2 + (j - 1) * self.reach
    }

    /// Where band `k`'s rows of step `j` start: a reach below its slices, whose sums read them
    /// (so where its slices of step `j - 1` start), but at the mesh's ends.
    fn row_line(&self, k: usize, j: usize, depth: usize) -> usize {
        let line = self.slice_line(k, j, depth);
        if k == 0 || k == self.bands.len() - 1 {
            line
        } else {
            line - self.reach
        }
    }

    /// `depth` steps over the bands of `blocks` blocks, doing `work`.
    fn run(&self, depth: usize, blocks: usize, work: &Work<'_>) -> Finite {
        let bands = self.bands.len() - 1;
        let progress: Vec<BandProgress> = (0..bands).map(|_| BandProgress::default()).collect();
        sweep::top_down(bands, |k| {
            let above = progress.get(k + 1);
            self.run_band(k, depth, blocks, work, &progress[k], above)
        })
    }

    /// Band `k`'s part of a sweep of `depth` steps over `blocks` blocks: the rows of step `j`
    /// over `[row_line(k, j), row_line(k + 1, j))` and its slices over
    /// `[slice_line(k, j), slice_line(k + 1, j))`, each step one reach behind the one before,
    /// then the steps' ends past the band's top boundary once the band above has done what
    /// they read there (`above`: its progress).
    fn run_band(
        &self,
        k: usize,
        depth: usize,
        blocks: usize,
        work: &Work<'_>,
        progress: &BandProgress,
        above: Option<&BandProgress>,
    ) -> Finite {
        let r = self.reach;
        let row_line = |k: usize, j: usize| self.row_line(k, j, depth).min(blocks);
        let slice_line = |k: usize, j: usize| self.slice_line(k, j, depth).min(blocks);
        let mut front = Front {
            rows: std::array::from_fn(|j| row_line(k, j.max(1))),
            slices: std::array::from_fn(|j| slice_line(k, j.max(1))),
            finite: [true; sweep::DEPTH + 1],
            work,
            progress,
        };
        for at in row_line(k, 1) + 1..=row_line(k + 1, 1) {
            front.rows_to(1, at);
            front.slices_to(1, front.rows[1]);
            for j in 2..=depth {
                // Rows read the positions of step j - 1 up to a reach past them, and overwrite
                // the rows that step j - 1's slices up to a reach past them sum.
                let end = front.slices[j - 1].saturating_sub(r);
                front.rows_to(j, end.min(row_line(k + 1, j)));
                front.slices_to(j, front.rows[j]);
            }
        }
        for j in 1..=depth {
            let (row_end, slice_end) = (row_line(k + 1, j), slice_line(k + 1, j));
            if let Some(above) = above.filter(|_| j > 1) {
                // Up to row_end, rows read the positions of step j - 1 a reach past it, the
                // band above's, and overwrite the rows of step j - 1 that its slices there sum.
                above
                    .slices
                    .wait_for(j - 1, slice_end.min(slice_line(k + 2, j - 1)));
            }
            front.rows_to(j, row_end);
            if let Some(above) = above {
                // Slices up to slice_end sum the band above's rows of step j up to it.
                above.rows.wait_for(j, slice_end.min(row_line(k + 2, j)));
            }
            front.slices_to(j, slice_end);
        }
        front.finite
    }

    /// The sweep over `rows` (each block's first spring row, and the end of the last) with
    /// `threads` threads, or `None` where it cannot run or would not pay: a spring with an end
    /// in a block before its row's, or rows reaching too far for bands 8 reaches wide, two of
    /// them on several threads (one band sweeps on one thread: the irregular bench mesh's
    /// scatter step took 0.53-0.58 ms so, against 0.35-0.36 plainly). As many steps per sweep
    /// as the gather's rule gives (`sweep::bands_and_depth`): the most, up to 6, that keep
    /// as many bands as two steps would, each 4 steps of reach wide; but no more than
    /// [`NARROW_BAND_DEPTH`] on bands narrower than [`WIDE_BAND`] blocks. (4 at most until
    /// 2026-12-05: on an AMD EPYC VM the 2048^2 grid's scatter step took 10.1-10.4 ms at 6
    /// against 10.3-10.7 at 4, seven runs each; see the performance log.)
    fn plan(
        springs: &SpringTable,
        rows: &[usize],
        spring_count: usize,
        threads: usize,
    ) -> Option<Self> {
        let blocks = rows.len() - 1;
        let block_of = |v: u32| v as usize / SPRING_BLOCK as usize;
        let reaches: Option<Vec<usize>> = (0..blocks)
            .into_par_iter()
            .map(|k| {
                let mut reach = 0;
                for row in rows[k]..rows[k + 1] {
                    let ends = springs.a.row(row).into_iter().zip(springs.b.row(row));
                    for (_, (a, b)) in (row * LANES..spring_count).zip(ends) {
                        if block_of(a.min(b)) < k {
                            return None;
                        }
                        reach = reach.max(block_of(a.max(b)) - k);
                    }
                }
                Some(reach)
            })
            .collect();
        let reach = reaches?.into_iter().max().unwrap_or(0);
        let (band_count, depth) = sweep::bands_and_depth(blocks, reach, threads)?;
        let depth = if blocks / band_count < WIDE_BAND {
            depth.min(NARROW_BAND_DEPTH)
        } else {
            depth
        };
        Some(Self {
            reach,
            bands: (0..=band_count).map(|b| b * blocks / band_count).collect(),
            depth,
        })
    }
}

/// What of a scatter step ran beside the last step's self-collision (see `crate::early`): per
/// block, whether its force rows were written, and per slice, whether it was summed and
/// integrated. Empty where nothing was.
#[derive(Debug, Default)]
pub(crate) struct Begun {
    pub rows: Vec<bool>,
    pub slices: Vec<bool>,
}

impl Begun {
    fn rows(&self, block: usize) -> bool {
        self.rows.get(block).copied().unwrap_or(false)
    }

    fn slice(&self, slice: usize) -> bool {
        self.slices.get(slice).copied().unwrap_or(false)
    }
}

/// A scatter mesh's steps over a sweep's buffers (see `sweep::Buffers`), a run of force rows
/// or of slices at a time: what a band of a sweep runs (see [`Blocks::sweep`]), and the pieces
/// of the next step that self-collision's waiting threads take up beside its passes (step 2:
/// see `crate::early`).
pub(crate) struct BlockSteps<'a> {
    blocks: &'a Blocks,
    isa: InstructionSet,
    springs: &'a SpringTable,
    incidence: &'a IncidenceTable,
    /// Where the forces go: a sweep's may be in its ring (see [`Forces::for_sweep`]).
    forces: Forces,
    integrator: &'a Integrator,
    buffers: &'a Buffers,
}

impl<'a> BlockSteps<'a> {
    #[allow(clippy::too_many_arguments)] // the step's inputs, passed on to its kernels
    pub(crate) fn new(
        blocks: &'a Blocks,
        isa: InstructionSet,
        springs: &'a SpringTable,
        incidence: &'a IncidenceTable,
        forces: Forces,
        integrator: &'a Integrator,
        buffers: &'a Buffers,
    ) -> Self {
        Self {
            blocks,
            isa,
            springs,
            incidence,
            forces,
            integrator,
            buffers,
        }
    }

    pub(crate) fn block_count(&self) -> usize {
        self.blocks.rows.len() - 1
    }

    /// Every block, the bands' first blocks first, then their second, and so on: what runs
    /// early then shortens each band of the step left alike. (Begun from the first block,
    /// the early blocks would empty the first band or two, and the step would wait as long
    /// as before for the thread holding the most bands left.) Each band's own blocks still
    /// come in order, so a block's slices find the rows before them written.
    pub(crate) fn block_order(&self) -> Vec<usize> {
        let bands = &self.blocks.bands;
        let widest = bands.windows(2).map(|w| w[1] - w[0]).max().unwrap_or(0);
        (0..widest)
            .flat_map(|i| {
                bands
                    .windows(2)
                    .map(move |w| w[0] + i)
                    .zip(bands.windows(2))
            })
            .filter(|(k, w)| *k < w[1])
            .map(|(k, _)| k)
            .collect()
    }

    /// The block that slice `slice` belongs to.
    pub(crate) fn block_of(slice: usize) -> usize {
        slice / BLOCK_SLICES
    }

    /// Block `k`'s force rows.
    pub(crate) fn rows_of(&self, k: usize) -> Range<usize> {
        self.blocks.rows[k]..self.blocks.rows[k + 1]
    }

    /// Block `k`'s slices.
    pub(crate) fn slices_of(&self, k: usize) -> Range<usize> {
        self.blocks.slices(k..k + 1)
    }

    /// The blocks whose force rows slice `slice` sums: from the first to its own.
    pub(crate) fn summed_blocks(&self, slice: usize) -> std::ops::RangeInclusive<usize> {
        self.blocks.first_block[slice] as usize..=Self::block_of(slice)
    }

    /// Computes force rows `rows` of step `j` (1-based) from the positions of step `j - 1`.
    ///
    /// # Safety
    /// While it runs, no other thread may read or write these rows, nor write the positions
    /// of their springs' ends.
    pub(crate) unsafe fn rows(&self, j: usize, rows: Range<usize>) {
        // SAFETY: the caller's guarantee.
        unsafe {
            let out = self.forces.rows(rows.clone());
            let positions = self.buffers.positions(j - 1);
            kernels::spring_forces(self.isa, self.springs, positions, rows.start, out);
        }
    }

    /// Sums and integrates `slices` of step `j`; true if every new position is finite.
    ///
    /// # Safety
    /// Every force row these slices sum (of [`BlockSteps::summed_blocks`]) must be written,
    /// and no thread may write it, nor touch these slices' outputs or write the positions
    /// their springs read, while this runs (see `sweep::Buffers::step`).
    pub(crate) unsafe fn slices(&self, j: usize, slices: Range<usize>) -> bool {
        let (isa, incidence, integrator) = (self.isa, self.incidence, self.integrator);
        // SAFETY: the caller's guarantee.
        unsafe {
            let view = self.forces.view();
            let kernel = |positions: Positions<'_>, chunk: VertexChunk<'_>| {
                // Every step's positions as axes: the accumulation reads its own from them.
                let current = Positions {
                    points: None,
                    ..positions
                };
                kernels::accumulate_and_integrate(
                    isa, incidence, view, integrator, current, None, chunk,
                )
            };
            self.buffers.step(j, slices, true, &kernel)
        }
    }
}

/// The runs of consecutive slices of `slices` that `keep` keeps.
pub(crate) fn runs(
    slices: Range<usize>,
    keep: impl Fn(&usize) -> bool,
) -> impl Iterator<Item = Range<usize>> {
    let mut at = slices.start;
    std::iter::from_fn(move || {
        while at < slices.end && !keep(&at) {
            at += 1;
        }
        let start = at;
        while at < slices.end && keep(&at) {
            at += 1;
        }
        (start < at).then_some(start..at)
    })
}

/// Scatter's spring forces as pointers that every band's task uses (see [`Forces::rows`]), and
/// the early step's pieces (see [`BlockSteps`]).
#[derive(Clone, Copy)]
pub(crate) struct Forces {
    axes: Option<[*mut Block; 3]>,
    points: Option<*mut [Point; LANES]>,
    /// Rows in the buffer.
    rows: usize,
}

// SAFETY: the bands' tasks use the buffer in disjoint ways (see the module docs).
unsafe impl Send for Forces {}
unsafe impl Sync for Forces {}

impl Forces {
    pub(crate) fn new(spring_forces: &mut SpringForces) -> Self {
        match spring_forces {
            SpringForces::Axes(axes) => Self {
                rows: axes.blocks(),
                axes: Some(axes.axes_mut().map(<[Block]>::as_mut_ptr)),
                points: None,
            },
            SpringForces::Points(rows) => Self {
                rows: rows.len(),
                axes: None,
                points: Some(rows.as_mut_ptr()),
            },
        }
    }

    /// Where a sweep keeps its forces: in `ring` (see `ring`), sized as `spring_forces`, if
    /// there is one, else in `spring_forces`.
    fn for_sweep(spring_forces: &mut SpringForces, ring: Option<&ForceRing>) -> Self {
        let plain = Self::new(spring_forces);
        let Some(ring) = ring else {
            return plain;
        };
        // The same arrays and rows, at the ring's addresses.
        Self {
            axes: plain
                .axes
                .map(|_| std::array::from_fn(|axis| ring.base(axis).cast())),
            points: plain.points.map(|_| ring.base(0).cast()),
            rows: plain.rows,
        }
    }

    /// Rows `rows` to write.
    ///
    /// # Safety
    /// While they are in use, no other thread may read or write them.
    unsafe fn rows<'a>(&self, rows: Range<usize>) -> ForceRows<'a> {
        assert!(
            rows.start <= rows.end && rows.end <= self.rows,
            "force rows out of bounds"
        );
        let (start, len) = (rows.start, rows.len());
        // SAFETY: in bounds (checked); the caller keeps other threads off them.
        unsafe {
            match (self.axes, self.points) {
                (Some(axes), _) => ForceRows::Axes(
                    axes.map(|axis| std::slice::from_raw_parts_mut(axis.add(start), len)),
                ),
                (None, Some(points)) => {
                    ForceRows::Points(std::slice::from_raw_parts_mut(points.add(start), len))
                }
                (None, None) => unreachable!("forces are axes or points"),
            }
        }
    }

    /// The whole buffer to read.
    ///
    /// # Safety
    /// Only rows that no thread writes while the view is in use may be read through it.
    unsafe fn view<'a>(&self) -> ForcesView<'a> {
        let len = self.rows * LANES;
        // SAFETY: the buffer holds `len` values; the caller's guarantee for the rest.
        unsafe {
            match (self.axes, self.points) {
                (Some(axes), _) => ForcesView::Axes(
                    axes.map(|axis| Floats::from_raw(axis.cast_const().cast(), len)),
                ),
                (None, Some(points)) => {
                    ForcesView::Points(Points::from_raw(points.cast_const().cast(), len))
                }
                (None, None) => unreachable!("forces are axes or points"),
            }
        }
    }
}

/// Where a step's new positions, points and deltas go, as pointers (see [`Outputs::chunk`]).
#[derive(Clone, Copy)]
pub(crate) struct Outputs {
    next: [*mut Block; 3],
    delta: [*mut Block; 3],
    points: Option<*mut [Point; LANES]>,
    slices: usize,
}

// SAFETY: the bands' tasks write disjoint slices (see the module docs).
unsafe impl Send for Outputs {}
unsafe impl Sync for Outputs {}

impl Outputs {
    pub(crate) fn new(
        next: &mut Soa,
        delta: &mut Soa,
        points: Option<&mut [[Point; LANES]]>,
    ) -> Self {
        Self {
            slices: next.blocks(),
            next: next.axes_mut().map(<[Block]>::as_mut_ptr),
            delta: delta.axes_mut().map(<[Block]>::as_mut_ptr),
            points: points.map(<[[Point; LANES]]>::as_mut_ptr),
        }
    }

    /// The outputs of `slices`.
    ///
    /// # Safety
    /// While the chunk is in use, no other thread may touch these slices.
    unsafe fn chunk<'a>(&self, slices: Range<usize>) -> VertexChunk<'a> {
        assert!(slices.end <= self.slices, "output slices out of bounds");
        let (start, len) = (slices.start, slices.len());
        let part =
            |axis: *mut Block| unsafe { std::slice::from_raw_parts_mut(axis.add(start), len) };
        VertexChunk {
            first_slice: start,
            next: self.next.map(part),
            axes: true,
            delta: self.delta.map(part),
            // SAFETY: as the axes.
            points: self
                .points
                .map(|points| unsafe { std::slice::from_raw_parts_mut(points.add(start), len) }),
        }
    }
}

#[cfg(test)]
mod tests {
    use hooke_core::Solver;
    use hooke_core::scene::{MeshSection, Scene};
    use hooke_testkit::benchmark_scene;

    use super::*;
    use crate::{CpuSolver, Method, Topology};

    /// A scatter solver that steps block by block, or one that never does; one that sweeps
    /// several steps at a time where it can, or one that never does.
    fn solver(scene: &Scene, threads: usize, blocks: bool, sweeps: bool) -> CpuSolver {
        let mut solver = CpuSolver::for_test(scene, Method::Scatter, threads);
        let plan = solver.blocks.as_mut().unwrap_or_else(|| {
            panic!("{} vertices", scene.model.vertex_count());
        });
        if !sweeps {
            plan.sweep = None;
        }
        if !blocks {
            solver.blocks = None;
        }
        solver
    }

    /// A grid and an irregular mesh just above the size that steps block by block.
    fn meshes() -> [(MeshSection, u32); 2] {
        [
            (MeshSection::unit_grid(384, 384), 384 * 384),
            (MeshSection::unit_irregular(140_000, 11), 140_000),
        ]
    }

    #[test]
    fn block_by_block_steps_give_the_states_of_plain_steps() {
        for (mesh, vertices) in meshes() {
            let scene = benchmark_scene(mesh, vertices);
            for threads in [1, 2, 3] {
                let mut plain = solver(&scene, threads, false, false);
                let mut blocked = solver(&scene, threads, true, false);
                let plan = blocked.blocks.clone().expect("planned");
                // Every band but the first has slices that wait for the band before it.
                assert!(
                    plan.band_count() >= 2,
                    "{vertices} vertices: {threads} threads"
                );
                for b in 1..plan.band_count() {
                    let start = plan.bands[b];
                    let slices = plan.slices(start..start + 1);
                    assert!(
                        slices
                            .clone()
                            .any(|s| (plan.first_block[s] as usize) < start),
                        "{vertices} vertices, band {b}: no slice waits"
                    );
                }
                let what = format!("{vertices} vertices, {threads} threads");
                plain.assert_steps_alike(&mut blocked, &[1, 5, 20], &what);
            }
        }
    }

    #[test]
    fn sweeps_over_blocks_give_the_states_of_plain_steps() {
        for (mesh, vertices) in meshes() {
            let scene = benchmark_scene(mesh, vertices);
            for threads in [1, 2, 3] {
                let mut plain = solver(&scene, threads, false, false);
                let mut swept = solver(&scene, threads, true, true);
                assert!(swept.can_sweep(), "{vertices} vertices, {threads} threads");
                let plan = swept.blocks.clone().and_then(|b| b.sweep).expect("planned");
                // Waiting slices and strips at band boundaries inside the mesh are tested too.
                assert!(plan.reach >= 1, "{vertices} vertices: {plan:?}");
                // The irregular mesh's rows read points, which the sweep's steps write too.
                assert_eq!(swept.reads_points, vertices != 384 * 384);
                if vertices == 384 * 384 {
                    // 144 blocks reaching 1 block: room for a band per thread.
                    assert_eq!(plan.bands.len() - 1, threads, "{plan:?}");
                }
                // Sweeps of every depth, odd ones included, and a lone step between them.
                let what = format!("{vertices} vertices, {threads} threads");
                plain.assert_steps_alike(&mut swept, &[4, 1, 2, 3, 7, 9], &what);
            }
        }
    }

    #[test]
    fn a_band_waits_for_the_band_above_before_its_steps_cross_into_it() {
        // The band above starts its first step's rows late, and its slices later still, so
        // the band below reaches the blocks past which it reads that band's rows and
        // positions first: it must wait for each, or its states are not those of plain steps.
        let [(mesh, vertices), _] = meshes();
        let scene = benchmark_scene(mesh, vertices);
        let mut plain = solver(&scene, 2, false, false);
        let mut swept = solver(&scene, 2, true, true);
        let blocks = swept.blocks.clone().expect("blocks");
        let plan = blocks.sweep.clone().expect("a sweep");
        assert_eq!(plan.bands.len() - 1, 2);
        let depth = 4; // even: the result lands in `current`, as plain steps leave it
        plain.step(depth as u32).expect("stable");
        let (late_rows, late_slices) = (plan.row_line(1, 1, depth), plan.slice_line(1, 1, depth));
        let pause = || std::thread::sleep(std::time::Duration::from_millis(100));
        let reads_points = swept.reads_points;
        let buffers = Buffers::of(&mut swept, reads_points);
        let (isa, integrator) = (swept.options.instruction_set, &swept.integrator);
        let Topology::Scatter {
            springs,
            incidence,
            spring_forces,
        } = &mut swept.topology
        else {
            panic!("scatter");
        };
        let tables = (&*springs, &*incidence);
        let finite = swept.pool.install(|| {
            // The forces in a ring where the system maps one, as sweeps keep them.
            let ring = blocks.force_ring(spring_forces);
            let forces = Forces::for_sweep(spring_forces, ring.as_ref());
            blocks.with_work(isa, tables, forces, integrator, &buffers, |work| {
                let rows = |j: usize, range: Range<usize>| {
                    if j == 1 && range.start == late_rows {
                        pause();
                    }
                    (work.rows)(j, range);
                };
                let slices = |j: usize, range: Range<usize>| {
                    if j == 1 && range.start == late_slices {
                        pause();
                    }
                    (work.slices)(j, range)
                };
                let slow = Work {
                    rows: &rows,
                    slices: &slices,
                };
                plan.run(depth, blocks.rows.len() - 1, &slow)
            })
        });
        assert!(finite.iter().all(|&f| f));
        assert!(
            hooke_testkit::state_of(&plain) == hooke_testkit::state_of(&swept),
            "the swept state differs"
        );
    }

    #[test]
    fn blocks_with_room_for_one_band_sweep_only_on_one_thread() {
        // Rows of 4,096 vertices: a spring reaches up to 4 blocks of 1,056 past its own, so
        // the 63 blocks hold one band 4 steps of reach wide even at 2 steps a sweep, which one
        // thread alone would sweep while the others waited.
        let scene = benchmark_scene(MeshSection::unit_grid(4096, 16), 4096 * 16);
        for (threads, depth) in [(1, Some(3)), (2, None), (3, None)] {
            let solver = CpuSolver::for_test(&scene, Method::Scatter, threads);
            let plan = solver.blocks.as_ref().expect("blocks");
            assert_eq!(plan.sweep_depth(), depth, "{threads} threads");
        }
    }

    #[test]
    fn blocks_sweep_the_most_steps_that_keep_a_band_per_thread() {
        // Rows of 2,048 vertices: a spring reaches up to 2 blocks past its own, so the 63
        // blocks hold two bands of 3 steps of reach (24 blocks), not of 4 (32); one band of
        // 63 blocks would hold 6, but sweeps 4, being narrower than `WIDE_BAND`.
        let scene = benchmark_scene(MeshSection::unit_grid(2048, 32), 2048 * 32);
        for (threads, depth) in [(1, 4), (2, 3)] {
            let solver = CpuSolver::for_test(&scene, Method::Scatter, threads);
            let plan = solver.blocks.as_ref().expect("blocks");
            assert_eq!(plan.sweep_depth(), Some(depth), "{threads} threads");
            assert_eq!(solver.steps_per_sweep(), depth, "{threads} threads");
        }
    }

    #[test]
    fn a_sweep_over_blocks_stops_at_the_first_step_that_blew_up() {
        let [(mesh, vertices), _] = meshes();
        let mut scene = benchmark_scene(mesh, vertices);
        scene.material.dt = 3.0 * scene.max_stable_dt;
        let blow_up = |sweeps| {
            let mut solver = solver(&scene, 2, true, sweeps);
            assert_eq!(solver.can_sweep(), sweeps);
            solver.step_until_blown_up()
        };
        let step = blow_up(true);
        assert!(step > 1 && step < 100_000);
        assert_eq!(step, blow_up(false));
    }
}
