//! Several steps per sweep over memory (temporal blocking), for meshes larger than the caches.
//!
//! A gather step reads every vertex's position, delta and integration constants and writes its
//! new position and delta. On a mesh whose working set leaves the caches, each step streams all
//! of that from memory, and the threads share the stream: the 1024^2 grid took 5.9x the 512^2
//! step for 4x the springs. A sweep instead advances a few slices at a time by up to
//! [`DEPTH`] steps while they are still in the cache: as many as leave each thread a band
//! (below).
//!
//! Step `j` of a sweep (1-based) reads `x(t + (j-1) dt)` and writes `x(t + j dt)` over
//! `x(t + (j-2) dt)`: odd steps from `current` into `next`, even steps back, the two buffers a
//! single step uses. A vertex's step `j` needs step `j-1` done within the mesh's *reach* `r`
//! (the furthest, in slices, any neighbour lies from a vertex), and may overwrite
//! `x(t + (j-2) dt)` only once no step `j-1` within `r` still reads it.
//!
//! The slices are cut into one band per thread, and each band's steps lean into the band above:
//! band `k`'s step `j` covers `[b_k + (j-1) l_k, b_{k+1} + (j-1) l_{k+1})`, where `b_k` is its
//! lower boundary and `l_k` the boundary's *lean*, the furthest any slice near it has a
//! neighbour (at most `r`; 0 at the mesh's ends, so the first band starts every step at 0 and
//! the last ends every step at the last slice). Within its band a thread runs step 1 over the
//! next few slices, then every later step as far as the dependencies allow (step `j` trails
//! step `j-1` by the reaches of the slices it is on, `r` at most), and so on to the band's top;
//! then it finishes steps `2..=depth` past its top boundary, each once the band above has done
//! its step `j-1` up to one lean past where step `j` ends (`Progress`): step `j` reads those
//! positions there, and overwrites the `x(t + (j-2) dt)` that they read. A band does its lowest
//! slices first, without waiting (it waits only at its top), so that wait is short or none;
//! bands are taken from the top down, so the band waited for is always running. Nothing else
//! crosses a boundary: band `k + 1`'s step `j` reads step `j-1` from one lean below its start,
//! where its own step `j-1` starts, and no step of band `k` reads what it overwrites. So no
//! slice waits for a second pass, and every band does as many slice-steps (the boundaries are
//! moved down by half the lean's `depth - 1` steps). An earlier schedule stopped each band's
//! steps `(j-1) r` short of both its ends and ran the strips left at each boundary in a second
//! pass, out of the caches: on the irregular bench mesh (reach 157) those strips took 15-17% of
//! a sweep's time.
//!
//! Every vertex does the arithmetic of a single step on the same inputs, so the states are
//! bit-identical (tested). Only steps where nothing acts between the spring forces and the next
//! step may sweep: no tearing, no per-step external forces (wind, drag, bending damping), no
//! colliders, handles or self-collision. Any other step runs alone. Scatter sweeps its blocks
//! of springs through the same [`Buffers`] (see `blocks`).

use std::ops::Range;
use std::sync::atomic::{AtomicUsize, Ordering};

use hooke_core::SimError;
use rayon::prelude::*;

use crate::blocks::Blocks;
use crate::kernels::{self, Block, GatherTable, Integrator, Point, VertexChunk};
use crate::layout::LANES;
use crate::ring::ForceRing;
use crate::view::Positions;
use crate::{CpuSolver, InstructionSet, Topology};

/// Steps per sweep at most. Four halve what two stream from memory again; six took 1-13% off
/// the 2048^2 grid's gather step in four pairs of runs on an Intel VM (no change beyond its
/// noise at the other sizes), eight nothing on an AMD one (see the performance log). A mesh
/// sweeps as many as leave each thread a band (see [`Sweep::of`]), and so do scatter's blocks.
pub(crate) const DEPTH: usize = 6;

/// Slices that step 1 advances by at a time: 2,048 vertices, so the slices every step of the
/// sweep is working on (up to `DEPTH` reaches behind) stay in a core's L2 cache on a grid up
/// to 2048^2, and each kernel call has thousands of vertices to amortise it.
const ADVANCE: usize = 256;

/// Slices a mesh needs at least for a sweep to pay: 65,536 vertices. On an Intel Xeon VM with
/// 2 MiB of L2 a core, the irregular bench mesh of 65,536 vertices (8.5 MiB a step) took
/// 0.23-0.24 ms a step sweeping against 0.26-0.28 without, and the 256^2 grid 0.152-0.157
/// against 0.161-0.162 (see the performance log); at 16,384 vertices, where a step's working
/// set stays in the caches, the 128^2 grid's step took 0.07 ms sweeping against 0.04.
const MIN_SLICES: usize = 8_192;

/// How a mesh sweeps: the reach of its springs, the bands its slices are cut into and how far
/// each band's steps lean into the next.
#[derive(Clone, Debug, PartialEq, Eq)]
pub(crate) struct Sweep {
    /// The furthest, in slices, that any vertex has a neighbour.
    reach: usize,
    bands: usize,
    /// Steps per sweep at most (2..=[`DEPTH`]).
    depth: usize,
    /// Per band boundary (`0..=bands`), the furthest any slice near it has a neighbour (see
    /// [`lean`]): each step of the band below reaches that much further past it than the step
    /// before. 0 at the mesh's ends, where no band leans.
    leans: Vec<usize>,
    /// Per slice `f` (`0..=slices`), the slices below which every slice's neighbours all lie
    /// below `f` (see [`behind`]): once step `j - 1` is done below `f`, step `j` may run up to
    /// there.
    behind: Vec<usize>,
    /// Whether every row reads its neighbours from the points: the steps before a sweep's last
    /// then write their positions as points only (the kernel reads a slice's own from them
    /// too), which keeps 24 bytes a vertex out of the caches (see [`Buffers::step`]).
    points_only: bool,
}

impl Sweep {
    /// How `topology` over `slices` slices sweeps with `threads` threads, or `None` where it
    /// would not pay or cannot: too small a mesh, neighbours too far apart for bands 8
    /// reaches wide (two of them on several threads), or scatter, which sweeps its blocks
    /// instead (see `blocks`).
    pub(crate) fn plan(topology: &Topology, slices: usize, threads: usize) -> Option<Self> {
        let Topology::Gather(table) = topology else {
            return None;
        };
        if slices < MIN_SLICES {
            return None;
        }
        Self::of(table, slices, threads)
    }

    /// [`Sweep::plan`] on a mesh of any size: the most steps per sweep that keep as many
    /// bands, each at least 4 steps of reach wide, as two steps would. Bands are the
    /// parallelism: a sweep on fewer bands than threads leaves threads idle (at 8 steps the
    /// irregular bench mesh fitted one band, and its step took 0.40 ms against 0.24 at 4), so
    /// a mesh that fits only one band on several threads does not sweep at all.
    fn of(table: &GatherTable, slices: usize, threads: usize) -> Option<Self> {
        let reaches = slice_reaches(table);
        let reach = reaches.iter().copied().max().unwrap_or(0);
        let (bands, depth) = bands_and_depth(slices, reach, threads)?;
        let leans = (0..=bands)
            .map(|k| match k {
                0 => 0,
                k if k == bands => 0,
                k => lean(&reaches, k * slices / bands, reach),
            })
            .collect();
        Some(Self {
            reach,
            bands,
            depth,
            leans,
            behind: behind(&reaches),
            points_only: table.neighbor.point_offsets().is_some(),
        })
    }

    /// Where band `k`'s step `j` (1-based) of a sweep of `depth` steps starts, so where band
    /// `k - 1`'s ends: boundary `k`, moved down by half its lean's `depth - 1` steps (which
    /// gives every band the same slice-steps), plus `j - 1` leans.
    fn line(&self, k: usize, j: usize, depth: usize, slices: usize) -> usize {
        if k == 0 {
            return 0;
        }
        if k == self.bands {
            return slices;
        }
        let lean = self.leans[k];
        k * slices / self.bands - (depth - 1) * lean / 2 + (j - 1) * lean
    }
}

/// The furthest, in slices, that each slice of `table` has a neighbour.
fn slice_reaches(table: &GatherTable) -> Vec<usize> {
    let slices = table.slices.slice_rows.len().saturating_sub(1);
    (0..slices)
        .into_par_iter()
        .map(|slice| {
            table
                .slices
                .rows(slice)
                .flat_map(|row| table.neighbor.row(row))
                .map(|neighbor| (neighbor as usize / LANES).abs_diff(slice))
                .max()
                .unwrap_or(0)
        })
        .collect()
}

/// Per slice `f` (`0..=slices`), the most slices `s` such that every slice below `s` has its
/// neighbours (within its reach) below `f`. Step `j` may run on such a slice once step `j - 1`
/// is done below `f`: it reads the positions of step `j - 1` there, and overwrites those of
/// step `j - 2` that only step `j - 1` of its neighbours reads. So each step trails the one
/// before by the reaches where it is, not by the mesh's furthest: on the irregular bench mesh
/// (reach 157 slices) by 88-117 slices for 80% of a band, which took a third off the misses
/// of a simulated 1 MiB L2 cache (cachegrind).
fn behind(reaches: &[usize]) -> Vec<usize> {
    let mut behind = Vec::with_capacity(reaches.len() + 1);
    let (mut s, mut furthest) = (0, 0);
    for f in 0..=reaches.len() {
        // `furthest`: one past the highest neighbour of any slice below `s`.
        while s < reaches.len() && furthest.max(s + reaches[s] + 1) <= f {
            furthest = furthest.max(s + reaches[s] + 1);
            s += 1;
        }
        behind.push(s);
    }
    behind
}

/// The lean at a band boundary `b`: the furthest any slice near it has a neighbour. Every
/// line a sweep's steps start or end at near `b` lies within `(DEPTH - 1) / 2` leans of it
/// (see [`Sweep::line`]), so a slice more than a reach further away has no neighbour across
/// any of them, and one nearer has none further than the lean. An irregular mesh's slices
/// mostly reach less than its furthest (the bench mesh: 48-103 slices for 94% of them, 157 at
/// most), so a lean may be shorter than the reach.
fn lean(reaches: &[usize], b: usize, reach: usize) -> usize {
    let zone = ((DEPTH - 1) * reach).div_ceil(2) + reach + 1;
    let near = b.saturating_sub(zone)..(b + zone).min(reaches.len());
    reaches[near].iter().copied().max().unwrap_or(0).max(1)
}

/// The bands and steps per sweep of [`Sweep::of`] for `units` slices (or scatter's blocks) of
/// this reach.
pub(crate) fn bands_and_depth(
    units: usize,
    reach: usize,
    threads: usize,
) -> Option<(usize, usize)> {
    let bands_of = |depth: usize| bands(units, 4 * depth * reach.max(1), threads);
    let most = bands_of(2)?;
    let depth = (2..=DEPTH).rev().find(|&d| bands_of(d) == Some(most))?;
    Some((most, depth))
}

/// How many bands at least `width` wide a sweep cuts `units` (slices, or scatter's blocks)
/// into: one per thread at most, and none where not even one fits or only one would on
/// several threads (that one thread would sweep while the others waited).
pub(crate) fn bands(units: usize, width: usize, threads: usize) -> Option<usize> {
    let bands = threads.min(units / width);
    let enough = if threads > 1 { 2 } else { 1 };
    (bands >= enough).then_some(bands)
}

/// The buffers of a sweep, as pointers that every band's thread uses (see [`Buffers::step`]).
#[derive(Clone, Copy)]
pub(crate) struct Buffers {
    /// Positions at even steps of the sweep (`current`) and at odd ones (`next`).
    positions: [[*mut Block; 3]; 2],
    /// The same as points, when the force pass reads them.
    points: [Option<*mut [Point; LANES]>; 2],
    delta: [*mut Block; 3],
    /// Slices in each buffer.
    slices: usize,
}

// SAFETY: the bands' threads use the buffers in disjoint ways (see the module docs and
// `Buffers::step`).
unsafe impl Send for Buffers {}
unsafe impl Sync for Buffers {}

/// The fused gather step of a run of slices, as [`Buffers::step`] runs it: nothing but the
/// springs acts on the vertices.
pub(crate) fn gather_run<'a>(
    isa: InstructionSet,
    table: &'a GatherTable,
    integrator: &'a Integrator,
) -> impl Fn(Positions<'_>, VertexChunk<'_>) -> bool + Sync + 'a {
    move |positions, chunk| {
        kernels::gather_and_integrate(isa, table, integrator, positions, None, chunk)
    }
}

impl Buffers {
    /// The buffers of `solver`'s sweep: `current` and `next` in turn, with their points when
    /// the force pass reads them.
    pub(crate) fn of(solver: &mut CpuSolver, reads_points: bool) -> Self {
        let points = |rows: &mut Vec<[Point; LANES]>| reads_points.then_some(rows.as_mut_ptr());
        Self {
            positions: [
                solver.current.axes_mut().map(<[Block]>::as_mut_ptr),
                solver.next.axes_mut().map(<[Block]>::as_mut_ptr),
            ],
            points: [points(&mut solver.points), points(&mut solver.next_points)],
            delta: solver.delta.axes_mut().map(<[Block]>::as_mut_ptr),
            slices: solver.numbering.slice_count(),
        }
    }

    /// The positions of step `j` of the sweep (`j = 0`: those it starts from).
    ///
    /// # Safety
    /// While the view is in use, no other thread may write what is read through it.
    pub(crate) unsafe fn positions<'a>(&self, j: usize) -> Positions<'a> {
        // SAFETY: the buffers hold `self.slices` slices; the caller's guarantee for the rest.
        unsafe {
            Positions::from_raw(
                self.positions[j % 2].map(|axis| axis.cast_const()),
                self.slices,
                self.points[j % 2].map(|points| points.cast_const()),
            )
        }
    }

    /// Runs step `j` of the sweep over `slices` with `kernel`, reading the positions of step
    /// `j - 1` and writing those of step `j` and the deltas. The positions go to the points
    /// where the buffers have them, and to the axes too with `axes` or where they have none.
    /// True if all results are finite.
    ///
    /// # Safety
    /// While it runs, no other thread may touch the slices it writes (`slices` of the
    /// positions of step `j`, the points and the deltas), nor write any it reads (those of
    /// step `j - 1` within the reach of `slices`). The module docs show the schedule that
    /// keeps to this.
    pub(crate) unsafe fn step(
        &self,
        j: usize,
        slices: Range<usize>,
        axes: bool,
        kernel: &(impl Fn(Positions<'_>, VertexChunk<'_>) -> bool + Sync),
    ) -> bool {
        if slices.is_empty() {
            return true;
        }
        assert!(slices.end <= self.slices, "sweep slices out of bounds");
        let write = j % 2;
        let (start, len) = (slices.start, slices.len());
        // SAFETY: the buffers hold `self.slices` slices (checked above), the caller keeps
        // other threads off what this writes, and writes nothing this reads.
        unsafe {
            let positions = self.positions(j - 1);
            let out = |axis: *mut Block| std::slice::from_raw_parts_mut(axis.add(start), len);
            let chunk = VertexChunk {
                first_slice: start,
                next: self.positions[write].map(out),
                axes: axes || self.points[write].is_none(),
                delta: self.delta.map(out),
                points: self.points[write]
                    .map(|points| std::slice::from_raw_parts_mut(points.add(start), len)),
            };
            kernel(positions, chunk)
        }
    }
}

/// Per step of a sweep (index `j`, 1-based), whether its results were all finite.
pub(crate) type Finite = [bool; DEPTH + 1];

/// Step by step, whether both were finite.
pub(crate) fn both(a: Finite, b: Finite) -> Finite {
    std::array::from_fn(|j| a[j] && b[j])
}

impl Sweep {
    /// `depth` steps over the bands, each slice advanced by `kernel` (see the module docs).
    fn run(
        &self,
        depth: usize,
        buffers: &Buffers,
        kernel: &(impl Fn(Positions<'_>, VertexChunk<'_>) -> bool + Sync),
    ) -> Finite {
        let slices = buffers.slices;
        let progress: Vec<Progress> = (0..self.bands).map(|_| Progress::default()).collect();
        top_down(self.bands, |k| {
            let above = progress.get(k + 1);
            self.run_band(k, depth, slices, buffers, kernel, &progress[k], above)
        })
    }

    /// Band `k`'s part of the sweep: step `j` over `[line(k, j), line(k + 1, j))`, each step
    /// behind the one before by the reaches where it is (see [`behind`]), then the steps' ends
    /// past the band's top boundary once the band above has done what they read
    /// there (`above`: its progress).
    #[allow(clippy::too_many_arguments)] // one band's share of `run`'s inputs
    fn run_band(
        &self,
        k: usize,
        depth: usize,
        slices: usize,
        buffers: &Buffers,
        kernel: &(impl Fn(Positions<'_>, VertexChunk<'_>) -> bool + Sync),
        progress: &Progress,
        above: Option<&Progress>,
    ) -> Finite {
        let line = |k: usize, j: usize| self.line(k, j, depth, slices);
        let mut finite: Finite = [true; DEPTH + 1];
        // Where step j has got to, from the band's lower line.
        let mut reached: [usize; DEPTH + 1] = std::array::from_fn(|j| line(k, j.max(1)));
        // Runs step j up to `limit` if it has not got there; where it has got to.
        let mut advance = |j: usize, limit: usize| {
            if limit > reached[j] {
                // SAFETY: the schedule of the module docs.
                let axes = j == depth || !self.points_only;
                finite[j] &= unsafe { buffers.step(j, reached[j]..limit, axes, kernel) };
                reached[j] = limit;
                progress.publish(j, limit);
            }
            reached[j]
        };
        let (mut at, top) = (line(k, 1), line(k + 1, 1));
        while at < top {
            let end = (at + ADVANCE).min(top);
            let mut front = advance(1, end);
            for j in 2..=depth {
                // Behind step j - 1 by the reaches there (so all that step j reads is done),
                // which also keeps it more than a lean short of line(k + 1, j - 1), where the
                // band above starts its step j - 1.
                front = advance(j, self.behind[front]);
            }
            at = end;
        }
        for j in 2..=depth {
            if let Some(above) = above {
                // Step j up to line(k + 1, j) reads step j - 1 of the band above up to one
                // lean past it, and overwrites the step j - 2 that its step j - 1 reads there.
                let lean = self.leans[k + 1];
                let needed = (line(k + 1, j) + lean).min(line(k + 2, j - 1));
                above.wait_for(j - 1, needed);
            }
            advance(j, line(k + 1, j));
        }
        finite
    }
}

/// Runs `band(k)` for every band `k < bands` in parallel, the bands taken from the top down, so
/// a band's upper neighbour, the only one it waits for, has always been taken by a thread that
/// is running it. Per step, whether every band's results were finite.
pub(crate) fn top_down(bands: usize, band: impl Fn(usize) -> Finite + Sync) -> Finite {
    let untaken = AtomicUsize::new(bands);
    let finite = (0..bands).into_par_iter().map(|_| {
        let k = untaken.fetch_sub(1, Ordering::Relaxed) - 1;
        band(k)
    });
    finite.reduce(|| [true; DEPTH + 1], both)
}

/// How far one band's steps have got: per step (1-based), the slice (or scatter's block) below
/// which it is done. Aligned to two cache lines (adjacent-line prefetching fetches lines in
/// pairs), so that two bands' stores never contend for one line.
#[derive(Default)]
#[repr(align(128))]
pub(crate) struct Progress {
    reached: [AtomicUsize; DEPTH + 1],
}

impl Progress {
    /// Tells the band below that step `j` is done below `slice`; what the step wrote there is
    /// visible to it once [`Progress::wait_for`] returns.
    pub(crate) fn publish(&self, j: usize, slice: usize) {
        self.reached[j].store(slice, Ordering::Release);
    }

    /// Waits until step `j` is done below `slice`. The band it belongs to has been taken by a
    /// running thread (see [`Sweep::run`]) and does those slices first, without waiting.
    pub(crate) fn wait_for(&self, j: usize, slice: usize) {
        let mut spins = 0u32;
        while self.reached[j].load(Ordering::Acquire) < slice {
            spins += 1;
            if spins < 1_000 {
                std::hint::spin_loop();
            } else {
                std::thread::yield_now();
            }
        }
    }
}

impl CpuSolver {
    /// Whether the next steps may run in one sweep (see the module docs).
    pub(crate) fn can_sweep(&self) -> bool {
        self.sweep_depth() > 1
            && self.only_self_collision_between_steps()
            && self.self_collision.is_none()
    }

    /// Steps per sweep at most where the mesh is laid out to sweep (large enough, neighbours
    /// near enough), whatever acts between its steps; 1 where it is not.
    pub(crate) fn sweep_depth(&self) -> usize {
        match &self.topology {
            Topology::Gather(_) => self.sweep.as_ref().map_or(1, |plan| plan.depth),
            Topology::Scatter { .. } => self
                .blocks
                .as_ref()
                .and_then(Blocks::sweep_depth)
                .unwrap_or(1),
        }
    }

    /// `depth` steps (2 up to the plan's depth) in one sweep; the states are those of as many
    /// single steps, and an error names the first step whose results were not all finite.
    pub(crate) fn step_sweep(&mut self, depth: usize) -> Result<(), SimError> {
        assert!((2..=self.sweep_depth()).contains(&depth) && self.can_sweep());
        let forked = |ring: &Option<ForceRing>| ring.as_ref().is_some_and(|r| !r.is_this_process());
        if self.force_ring.get().is_some_and(forked) {
            // Its pages are shared with the process it was forked from: map new ones.
            self.force_ring = std::sync::OnceLock::new();
        }
        let isa = self.options.instruction_set;
        let reads_points = self.refresh_points();
        let buffers = Buffers::of(self, reads_points);
        let integrator = &self.integrator;
        let finite = match &mut self.topology {
            Topology::Gather(table) => {
                let sweep = self.sweep.as_ref().expect("can_sweep checked the plan");
                sweep.run(depth, &buffers, &gather_run(isa, table, integrator))
            }
            Topology::Scatter {
                springs,
                incidence,
                spring_forces,
            } => {
                let blocks = self.blocks.as_ref().expect("can_sweep checked the plan");
                let tables = (&*springs, &*incidence);
                let ring = self
                    .force_ring
                    .get_or_init(|| blocks.force_ring(spring_forces));
                let ring = ring.as_ref();
                blocks.sweep(
                    depth,
                    isa,
                    tables,
                    spring_forces,
                    ring,
                    integrator,
                    &buffers,
                )
            }
        };
        // Stop at the first step with a result that is not finite, as single steps would.
        let last = (1..=depth).find(|&j| !finite[j]).unwrap_or(depth);
        if last % 2 == 1 {
            std::mem::swap(&mut self.current, &mut self.next);
            std::mem::swap(&mut self.points, &mut self.next_points);
        }
        if reads_points && last < depth {
            // Its steps before the last wrote their positions as points only.
            self.axes_from_points();
        }
        self.points_fresh = reads_points && finite[last];
        self.steps_taken += last as u64;
        self.check_finite(finite[last])
    }
}

#[cfg(test)]
mod tests {
    use hooke_core::Solver;
    use hooke_core::scene::{MeshSection, Scene};
    use hooke_core::selfcollide::SelfCollision;
    use hooke_testkit::benchmark_scene;

    use super::*;
    use crate::Method;

    /// A gather solver that sweeps wherever it can, even on a mesh below [`MIN_SLICES`], or
    /// one that never does.
    fn solver(scene: &Scene, threads: usize, sweeps: bool) -> CpuSolver {
        let mut solver = CpuSolver::for_test(scene, Method::Gather, threads);
        solver.sweep = match &solver.topology {
            Topology::Gather(table) if sweeps => {
                Sweep::of(table, solver.numbering.slice_count(), threads)
            }
            _ => None,
        };
        assert_eq!(solver.can_sweep(), sweeps);
        solver
    }

    #[test]
    fn sweeps_give_the_states_of_single_steps() {
        let meshes = [
            (MeshSection::unit_grid(96, 96), 96 * 96, false),
            (MeshSection::unit_irregular(40_000, 11), 40_000, true),
        ];
        for (mesh, vertices, reads_points) in meshes {
            let scene = benchmark_scene(mesh, vertices);
            for threads in [1, 2, 3] {
                let mut single = solver(&scene, threads, false);
                let mut swept = solver(&scene, threads, true);
                let plan = swept.sweep.clone().expect("planned");
                // Bands meet inside the mesh: their boundaries' steps are tested too.
                assert!(
                    plan.bands > 1 || threads == 1,
                    "{vertices} vertices: {plan:?}"
                );
                assert_eq!(swept.reads_points, reads_points);
                let steps = format!("up to {} steps per sweep", plan.depth);
                assert!(swept.describe().contains(&steps), "{}", swept.describe());
                // Self-collision acts between steps: the description claims no sweep then.
                let config = SelfCollision::for_model(&scene.model);
                swept.set_self_collision(Some(config)).expect("set");
                assert!(!swept.describe().contains("sweep"), "{}", swept.describe());
                swept.set_self_collision(None).expect("unset");
                assert!(
                    !single.describe().contains("sweep"),
                    "{}",
                    single.describe()
                );
                // Sweeps of every depth, odd ones included, and a lone step between them.
                let what = format!("{vertices} vertices, {threads} threads");
                single.assert_steps_alike(&mut swept, &[4, 1, 2, 3, 7, 9], &what);
            }
        }
    }

    #[test]
    fn a_band_waits_for_the_band_above_before_its_steps_cross_into_it() {
        // The band above starts its first step late, so the band below reaches the lines past
        // which it reads that band's slices first: it must wait, or its states are not those of
        // single steps.
        let scene = benchmark_scene(MeshSection::unit_grid(96, 96), 96 * 96);
        let mut single = solver(&scene, 2, false);
        let mut swept = solver(&scene, 2, true);
        let plan = swept.sweep.clone().expect("planned");
        assert_eq!(plan.bands, 2);
        let depth = 4; // even: the result lands in `current`, as single steps leave it
        assert!(plan.depth >= depth);
        single.step(depth as u32).expect("stable");
        let slices = swept.numbering.slice_count();
        let late = plan.line(1, 1, depth, slices);
        let buffers = Buffers::of(&mut swept, false);
        let (isa, integrator) = (swept.options.instruction_set, &swept.integrator);
        let Topology::Gather(table) = &swept.topology else {
            panic!("gather");
        };
        let kernel = |positions: Positions<'_>, chunk: VertexChunk<'_>| {
            if chunk.first_slice == late {
                std::thread::sleep(std::time::Duration::from_millis(100));
            }
            kernels::gather_and_integrate(isa, table, integrator, positions, None, chunk)
        };
        let finite = swept.pool.install(|| plan.run(depth, &buffers, &kernel));
        assert!(finite.iter().all(|&f| f));
        assert!(
            hooke_testkit::state_of(&single) == hooke_testkit::state_of(&swept),
            "the swept state differs"
        );
    }

    #[test]
    fn a_mesh_sweeps_as_many_steps_as_keep_its_bands() {
        // The 256^2 grid (reach 33) and the irregular bench mesh (157) on 2 threads: 6 steps.
        assert_eq!(bands_and_depth(8192, 33, 2), Some((2, 6)));
        assert_eq!(bands_and_depth(8192, 157, 2), Some((2, 6)));
        // Reaching further, fewer steps keep two bands ...
        assert_eq!(bands_and_depth(8192, 300, 2), Some((2, 3)));
        // ... and many threads as many bands as two steps allow.
        assert_eq!(bands_and_depth(8192, 33, 64), Some((31, 2)));
        // One band: one thread sweeps, or none.
        assert_eq!(bands_and_depth(8192, 600, 1), Some((1, 3)));
        assert_eq!(bands_and_depth(8192, 600, 2), None);
        assert_eq!(bands_and_depth(8192, 2000, 1), None);
    }
    #[test]
    fn a_step_trails_the_one_before_by_the_reaches_where_it_is() {
        // Slice 2 reaches 5 slices; the others 1 or none.
        let reaches = [1, 1, 5, 1, 0, 1, 1, 1, 1, 0];
        let behind = behind(&reaches);
        assert_eq!(behind.len(), reaches.len() + 1);
        // Slice 2 waits until step j - 1 is past its neighbour 7; then a slice or two behind.
        assert_eq!(&behind[..], &[0, 0, 1, 2, 2, 2, 2, 2, 7, 8, 10]);
        for (f, &s) in behind.iter().enumerate() {
            // Every slice below `s` has its neighbours below `f` ...
            assert!((0..s).all(|below| below + reaches[below] < f), "f = {f}");
            // ... and the next one has not: `s` is the most.
            assert!(s == reaches.len() || s + reaches[s] >= f, "f = {f}");
        }
    }

    #[test]
    fn a_sweep_stops_at_the_first_step_that_blew_up() {
        // The grid's sweeps write every step's positions as axes; the irregular mesh's only
        // the last step's, so a sweep that stops before it takes them from the points, and
        // leaves the positions that writing axes would have.
        let meshes = [
            (MeshSection::unit_grid(96, 96), 96 * 96),
            (MeshSection::unit_irregular(40_000, 11), 40_000),
        ];
        for (mesh, vertices) in meshes {
            let mut scene = benchmark_scene(mesh, vertices);
            let depth = solver(&scene, 2, true).steps_per_sweep() as u64;
            let blown_up_at = |scene: &Scene| solver(scene, 2, true).step_until_blown_up();
            // A step in a sweep whose positions only the points hold: an even one.
            let bound = scene.max_stable_dt;
            scene.material.dt = (0..16)
                .map(|k| (3.0 + 0.25 * k as f64) * bound)
                .find(|&dt| {
                    scene.material.dt = dt;
                    let in_sweep = blown_up_at(&scene) % depth;
                    in_sweep != 0 && in_sweep.is_multiple_of(2)
                })
                .expect("a blow-up at an even step of a sweep");
            let blow_up = |sweeps, points_only| {
                let mut solver = solver(&scene, 2, sweeps);
                if let Some(sweep) = &mut solver.sweep {
                    sweep.points_only &= points_only;
                }
                let step = solver.step_until_blown_up();
                let state = solver.read_state().unwrap();
                let bits = |p: &glam::DVec3| p.to_array().map(f64::to_bits);
                (step, state.positions.iter().map(bits).collect::<Vec<_>>())
            };
            let (step, positions) = blow_up(true, true);
            assert!(
                step > 1 && step < 100_000 && step % depth != 0,
                "step {step}"
            );
            assert_eq!(step, blow_up(false, false).0);
            assert!((step, positions) == blow_up(true, false));
        }
    }
}
