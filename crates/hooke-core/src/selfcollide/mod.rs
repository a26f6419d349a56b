//! Approximate self-collision by binning (paper Section 5, after Kipfer et al. 2004), and the
//! exact search that measures what it misses.
//!
//! One pass per grid: every vertex gets the key of the grid cell holding it, a stable sort by
//! key puts vertices of the same cell next to each other, and each vertex is tested against the
//! vertices of its cell next to it in sorted order, at most `window` on either side. A pair closer than `distance` that no
//! spring joins is pushed apart to `distance`, each end by its share of the inverse masses (a
//! pinned end does not move), in the Verlet scheme's way: the new position moves and the
//! step's motion with it, so the pair stops approaching rather than bouncing.
//!
//! Grids are staggered: grid `k` of `K` is shifted by `k / K` of a cell along the diagonal
//! `(1, 1, 1)`, so two points that straddle a face of one grid's cell usually share a cell of
//! another. The passes run one after another on the corrected positions, so a pair found by
//! two grids is corrected once.
//!
//! Keys hash the cell's integer coordinates (Teschner et al. 2003) into `key_bits` bits, so the
//! grid needs no bounds. A hash collision puts the vertices of far cells in the same run of
//! keys; a window passes over them (it counts only vertices of its own cell), so what a window
//! holds depends only on which vertices share the cell. Everything here is float32, the same arithmetic as the GPU's
//! `self_collide.wgsl`, so the CPU and GPU sort the same keys into the same order.

mod ahead;
mod along_surface;
mod awake;
mod binning;
mod culling;
mod disjoint;
mod keyed;
mod nearby;
mod parts;
mod points;
mod wide;

use std::collections::HashMap;

use glam::{IVec3, Vec3};
use rayon::prelude::*;

use ahead::Ahead;
pub use along_surface::{along_surface, layered_patches, patch_order, split_patches};
pub use awake::Idle;
use awake::{NoIdle, with_pool_awake};
use binning::{Binning, Entry, key_of, vertex_of};
pub use culling::{Culling, Proof, Zone};
use keyed::{Keyed, sorted_with_suspects};
use nearby::Nearby;
pub use parts::{PartTimes, Stopwatch};
pub use points::{BlockPoints, LANES, Points};

use crate::{Adjacency, Model};

/// How self-collision is found and resolved.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct SelfCollision {
    /// Non-adjacent vertices are kept at least this far apart, m (the cloth's thickness).
    pub distance: f64,
    /// Edge of a grid cell, m.
    pub cell_size: f64,
    /// Staggered grids `K`, one pass each.
    pub grids: u32,
    /// Vertices tested on each side of a vertex in sorted order.
    pub window: u32,
}

/// Largest `K` accepted (passes per step grow with it).
pub const MAX_GRIDS: u32 = 16;
/// Largest window accepted.
pub const MAX_WINDOW: u32 = 64;

impl SelfCollision {
    /// A setting for a model whose scene names none: vertices kept half the shortest spring
    /// apart, cells twice as wide, 4 grids, a window of 4.
    pub fn for_model(model: &Model) -> Self {
        let shortest = model
            .rest_lengths
            .iter()
            .copied()
            .filter(|l| *l > 0.0)
            .fold(f64::INFINITY, f64::min);
        let distance = if shortest.is_finite() {
            0.5 * shortest
        } else {
            0.01
        };
        Self {
            distance,
            cell_size: 2.0 * distance,
            grids: 4,
            window: 4,
        }
    }

    /// Shift of grid `k`, in cells, along each axis.
    pub fn grid_offset(&self, k: u32) -> f32 {
        k as f32 / self.grids as f32
    }
}

/// Key bits for `vertices` points: a table of at least twice as many keys as points, rounded
/// up to whole bytes so the 4-bit radix sort runs an even number of passes.
pub fn key_bits(vertices: usize) -> u32 {
    let needed = (2 * vertices.max(128)).next_power_of_two().trailing_zeros();
    (needed.div_ceil(8) * 8).min(32)
}

/// The cell of `p` in a grid of cells `1 / inverse_cell` wide shifted by `offset` cells.
#[inline(always)]
pub fn cell_of(p: Vec3, inverse_cell: f32, offset: f32) -> IVec3 {
    let x = p * inverse_cell + Vec3::splat(offset);
    IVec3::new(floor(x.x), floor(x.y), floor(x.z))
}

/// `x.floor() as i32` for |x| < 2e9 (further out, and for NaN, the floor of `x` clamped to
/// +-2e9), in operations a loop over many points vectorises: without a libm call (the baseline
/// x86-64 target has no rounding instruction), and without `as i32`, whose saturation the
/// compiler does not vectorise (4 key passes at 512^2 took 2.3x as long with it).
#[inline(always)]
#[allow(unsafe_code)]
// Not `clamp`: it passes NaN through, which the conversion below must not get.
#[allow(clippy::manual_clamp)]
fn floor(x: f32) -> i32 {
    // `max` returns -2e9 for NaN, so `clamped` is finite and within i32.
    let clamped = x.max(-2.0e9).min(2.0e9);
    // SAFETY: `clamped` is finite and its truncation fits in an i32.
    let truncated: i32 = unsafe { clamped.to_int_unchecked() };
    truncated - i32::from(truncated as f32 > clamped)
}

/// The sort key of `cell`: its coordinates hashed into `bits` bits.
#[inline(always)]
pub fn cell_key(cell: IVec3, bits: u32) -> u32 {
    let hash = (cell.x as u32).wrapping_mul(73_856_093)
        ^ (cell.y as u32).wrapping_mul(19_349_663)
        ^ (cell.z as u32).wrapping_mul(83_492_791);
    if bits >= 32 {
        hash
    } else {
        hash & ((1 << bits) - 1)
    }
}

/// Weights for [`resolve`]: inverse masses, zero for pinned vertices.
pub fn inverse_masses(model: &Model) -> Vec<f32> {
    model
        .masses
        .iter()
        .zip(&model.pinned)
        .map(|(m, pinned)| if *pinned { 0.0 } else { (1.0 / m) as f32 })
        .collect()
}

/// Stable sort of vertex indices by key: `(sorted keys, vertices in sorted order)`.
pub fn sort_by_key(keys: &[u32]) -> (Vec<u32>, Vec<u32>) {
    Binning::default()
        .sort_keys(keys, 32)
        .iter()
        .map(|&entry| (key_of(entry), vertex_of(entry)))
        .unzip()
}

/// True if a spring joins `a` and `b`.
pub fn joined(adjacency: &Adjacency, a: u32, b: u32) -> bool {
    adjacency.neighbors_of(a).contains(&b)
}

/// How grid `k` keys points.
struct GridKeys {
    inverse_cell: f32,
    offset: f32,
    bits: u32,
}

impl GridKeys {
    fn new(vertices: usize, config: &SelfCollision, k: u32) -> Self {
        Self::with_bits(key_bits(vertices), config, k)
    }

    fn with_bits(bits: u32, config: &SelfCollision, k: u32) -> Self {
        Self {
            inverse_cell: (1.0 / config.cell_size) as f32,
            offset: config.grid_offset(k),
            bits,
        }
    }

    #[inline(always)]
    fn of(&self, p: Vec3) -> u32 {
        cell_key(self.cell(p), self.bits)
    }

    #[inline(always)]
    fn cell(&self, p: Vec3) -> IVec3 {
        cell_of(p, self.inverse_cell, self.offset)
    }

    /// The keys of `points`' first `out.len()`, in a loop the compiler vectorises.
    #[inline(always)]
    fn batch(&self, points: &[Vec3], out: &mut [u32]) {
        for (key, &p) in out.iter_mut().zip(points) {
            *key = self.of(p);
        }
    }
}

/// The vertices in sorted order by `keys`, with their keys.
fn sorted_for_grid<'a>(
    binning: &'a mut Binning,
    positions: &[Vec3],
    keys: &GridKeys,
) -> &'a [Entry] {
    binning.sort(positions.len(), keys.bits, |first, out| {
        keys.batch(&positions[first..], out)
    })
}

/// The window of sorted slot `j`: the `window` slots nearest it on each side whose entry
/// lies in the same cell (`in_cell`), below `j` first, then above, nearest first. They are
/// looked for among the slots of the same key, which also hold the vertices of far cells
/// hashed alike: those are passed over, so they take no place in a window, and the window
/// depends only on which vertices share the cell. Yields the entries' indices.
fn window_of<'a>(
    j: usize,
    window: u32,
    sorted: &'a [Entry],
    positions: &'a [Vec3],
    keys: &'a GridKeys,
) -> impl Iterator<Item = u32> + 'a {
    let cell = keys.cell(positions[vertex_of(sorted[j]) as usize]);
    let in_cell = move |f: u32| keys.cell(positions[f as usize]) == cell;
    let w = window as usize;
    same_key_run((0..j).rev(), sorted, j, w, in_cell).chain(same_key_run(
        j + 1..sorted.len(),
        sorted,
        j,
        w,
        in_cell,
    ))
}

/// The first `w` entries of `slots` in `sorted` that `in_cell` takes, up to the first slot
/// whose key is not slot `j`'s.
fn same_key_run<'a, I: Iterator<Item = usize> + 'a>(
    slots: I,
    sorted: &'a [Entry],
    j: usize,
    w: usize,
    in_cell: impl Fn(u32) -> bool + 'a,
) -> impl Iterator<Item = u32> + 'a {
    let key = key_of(sorted[j]);
    slots
        .take_while(move |&m| key_of(sorted[m]) == key)
        .map(move |m| vertex_of(sorted[m]))
        .filter(move |&f| in_cell(f))
        .take(w)
}

/// Sorted slots per parallel task of the window test: two tasks per thread, of 256 to 4096
/// slots. A local pass's ~10,000 slots at 512^2 made 3 tasks of 4096: its window tests took
/// 0.46-0.53 ms a step on 16 threads against 0.25-0.27 in tasks of 1024, and 0.36-0.46 on 2
/// threads against 0.30-0.31 in four tasks. Since a local pass sorts only the vertices that
/// share a key with a suspect (see `keyed`), it holds 1,000-3,000 slots at 512^2 in
/// contact, which tasks of at least 1024 left on one thread, or cut into three of which one
/// thread tested two while the other waited. On alternate steps of the same runs of the
/// 512^2 workload, in four tasks against that: at 3,000 slots 151-155 us a step against
/// 231-235, at 1,000 55-60 against 75-77, at 2,300 116-125 against 121-129 (two runs each;
/// a third, in a slow spell of the VM, read the other way). Eight tasks (four a thread) took
/// 170 us against 160 for four; two (one a thread) 254 against 229 for three of 1024.
fn window_task(slots: usize) -> usize {
    (slots / (2 * rayon::current_num_threads().max(1))).clamp(256, 4096)
}

/// Crowded slots ahead of the one being tested whose position the window test asks for: a
/// position sits at a random address, in the last-level cache at best, and waiting for each
/// load in turn took most of the window test's time.
const PREFETCH_AHEAD: usize = 16;

/// Starts loading `value`'s cache line (a hint; nothing on other architectures).
#[inline(always)]
#[allow(unsafe_code)]
fn prefetch<T>(value: &T) {
    // SAFETY: SSE, which the intrinsic needs, is part of every x86-64 CPU; a prefetch reads
    // nothing architecturally and cannot fault, and `value` is a valid reference anyway.
    #[cfg(target_arch = "x86_64")]
    unsafe {
        std::arch::x86_64::_mm_prefetch::<{ std::arch::x86_64::_MM_HINT_T0 }>(
            (value as *const T).cast(),
        );
    }
    #[cfg(not(target_arch = "x86_64"))]
    let _ = value;
}

/// Starts loading the cache lines of `values`, a [`prefetch`] every 64 bytes from the first.
#[inline(always)]
fn prefetch_lines<T>(values: &[T]) {
    let step = (64 / std::mem::size_of::<T>().max(1)).max(1);
    values.iter().step_by(step).for_each(prefetch);
}

/// The sorted slots of `slots` that share their key with a slot beside them ("crowded"; most
/// vertices are alone in their cell) and whose entry `tested` takes, in order.
///
/// Without a branch per slot: whether a slot is crowded or tested follows no pattern a
/// branch predictor could learn, and a misprediction or two per slot cost as much as the
/// window tests of the few slots that are kept.
fn crowded_slots(
    slots: std::ops::Range<usize>,
    sorted: &[Entry],
    tested: impl Fn(u32) -> bool,
) -> Vec<usize> {
    let last = sorted.len().saturating_sub(1);
    let mut crowded = vec![0; slots.len()];
    let mut count = 0;
    for j in slots {
        let key = key_of(sorted[j]);
        let before = (j > 0) & (key_of(sorted[j.saturating_sub(1)]) == key);
        let after = (j < last) & (key_of(sorted[(j + 1).min(last)]) == key);
        crowded[count] = j;
        count += usize::from((before | after) & tested(vertex_of(sorted[j])));
    }
    crowded.truncate(count);
    crowded
}

/// Resolves self-collisions in place: `K` passes, each moving the `positions` of vertices
/// closer than `config.distance` to an unjoined window neighbour. `weights` are the inverse
/// masses (any common scale; zero for a pinned vertex). Returns every move in the order made
/// (a vertex appears once per grid that moved it), for callers that keep the step's motion
/// or a copy of the positions elsewhere: most vertices do not move.
pub fn resolve(
    positions: &mut [Vec3],
    weights: &[f32],
    adjacency: &Adjacency,
    config: &SelfCollision,
) -> Vec<(u32, Vec3)> {
    resolve_with(
        &mut Binning::default(),
        positions,
        weights,
        adjacency,
        config,
    )
}

/// Suspect vertices above this share of all (1 in 8) make a step run the full passes: sorting
/// every vertex then costs little more than finding those that share a suspect's key.
const LOCAL_AT_MOST: usize = 8;

/// Most steps run without a proof after proofs that did not help: on a cloth piled on itself
/// every proof fails, and one costs more than the passes it would have saved.
const MOST_UNPROVED: u32 = 64;

/// Self-collision's state kept by a solver from one step to the next: the sort's buffers, and
/// the culling that proves, most steps, that the passes would move nothing, and on most other
/// steps which few vertices they could move.
#[derive(Debug)]
pub struct Resolver {
    binning: Binning,
    /// The keys of a local pass sorted on its own (without `ahead`).
    keyed: Keyed,
    /// Every grid's sort of a step's local passes, made before the first (see `ahead`).
    ahead: Ahead,
    culling: Culling,
    /// The step's positions in mesh order, copied only when full passes run.
    positions: Vec<Vec3>,
    /// What local passes sort: the suspects and the vertices that may share a cell with one,
    /// and how far each has moved this step.
    nearby: Nearby,
    /// Passes that tested only suspect vertices.
    local_passes: u64,
    /// Steps with more suspects than one vertex in this many run the full passes.
    local_at_most: usize,
    /// The key bits of a local pass that sorts this many vertices.
    local_key_bits: fn(usize) -> u32,
    /// Steps to run without a proof, and how many the last proof that did not help gave.
    unproved: u32,
    backoff: u32,
    /// Steps run without a proof.
    unproved_steps: u64,
    /// Where the last step's time went, when `timing`.
    parts: PartTimes,
    timing: bool,
}

impl Default for Resolver {
    fn default() -> Self {
        Self {
            binning: Binning::default(),
            keyed: Keyed::default(),
            ahead: Ahead::default(),
            culling: Culling::default(),
            positions: Vec::new(),
            nearby: Nearby::default(),
            local_passes: 0,
            local_at_most: LOCAL_AT_MOST,
            local_key_bits: key_bits,
            unproved: 0,
            backoff: 0,
            parts: PartTimes::default(),
            timing: false,
            unproved_steps: 0,
        }
    }
}

/// Work a resolver's caller does beside a step's local passes, on the vertices outside the
/// step's [`Zone`] (see [`Resolver::resolve_beside`]).
pub trait Beside: Idle {
    /// The step's zone, once the proof has found it (at most once a step, before any pass);
    /// [`Idle::run_one`] is asked for pieces of work from then until the step's passes end.
    fn offer(&self, zone: Zone);
}

impl Resolver {
    /// [`resolve`]: the same moves, each vertex's in the same order (a local pass lists its
    /// moves in an order of its own, see `local_pass`). The passes are skipped when the culling
    /// shows that no unjoined pair is closer than the distance, since then none would move.
    /// When it shows that only a few vertices' pairs can be, a pass tests only their windows:
    /// it sorts only them and the vertices that may share a cell with one of them (see
    /// [`nearby`]), which gives each of their windows the same vertices as the full sort. A
    /// vertex that has moved further than the culling's margin widens the suspects to every
    /// patch it may have come near. After a proof that left passes to run in full, the next
    /// 1, 2, 4 ... up to 64 steps run the full passes without one.
    ///
    /// `points` are read where their owner keeps them; only a step whose full passes run
    /// copies them all into mesh order. The culling keeps their places ([`Points::place`]), so
    /// one resolver serves one owner's positions.
    ///
    /// The current pool's other threads stay awake for the whole call (see `awake`).
    pub fn resolve<P: Points + ?Sized>(
        &mut self,
        points: &P,
        weights: &[f32],
        adjacency: &Adjacency,
        config: &SelfCollision,
    ) -> Vec<(u32, Vec3)> {
        self.resolve_beside(points, weights, adjacency, config, None)
    }

    /// [`Resolver::resolve`], offering `beside` the step's [`Zone`] once the proof has shown
    /// that only a few vertices' pairs can be too close; the pool's other threads then take
    /// up `beside`'s pieces of work whenever the passes leave them waiting. The passes stay
    /// local for the rest of the step once it is offered (a local pass gives a full pass's
    /// moves, so that changes no bit), so no vertex outside the zone moves.
    pub fn resolve_beside<P: Points + ?Sized>(
        &mut self,
        points: &P,
        weights: &[f32],
        adjacency: &Adjacency,
        config: &SelfCollision,
        beside: Option<&dyn Beside>,
    ) -> Vec<(u32, Vec3)> {
        self.parts = PartTimes::default();
        let idle: &dyn Idle = match beside {
            Some(beside) => beside,
            None => &NoIdle,
        };
        // Dozens of short parallel passes: the pool's other threads wait for them awake.
        with_pool_awake(idle, || {
            self.prove_then_pass(points, weights, adjacency, config, beside)
        })
    }

    /// [`Resolver::resolve`] on the current thread.
    fn prove_then_pass<P: Points + ?Sized>(
        &mut self,
        points: &P,
        weights: &[f32],
        adjacency: &Adjacency,
        config: &SelfCollision,
        beside: Option<&dyn Beside>,
    ) -> Vec<(u32, Vec3)> {
        let proof = if self.unproved > 0 {
            self.unproved -= 1;
            self.unproved_steps += 1;
            None
        } else {
            let mut watch = Stopwatch::start(self.timing);
            let proof = self
                .culling
                .prove(points, adjacency, config.distance as f32);
            self.parts.measuring = self.culling.measuring();
            self.parts.pairs = watch.lap().saturating_sub(self.parts.measuring);
            if proof == Proof::Clear {
                self.backoff = 0;
                return Vec::new();
            }
            Some(proof)
        };
        self.passes(points, weights, adjacency, config, proof, beside)
    }

    /// How far from the suspects' boxes of the proof a vertex that a step's local passes
    /// move may lie, m. A pass moves a vertex by at most the distance for each of the `2
    /// window` neighbours of its window; a vertex moved past the margin after a pass makes
    /// suspect those within [`Culling::widening_reach`] of where it got to, which move from
    /// the next pass on. Along a chain of such widenings the passes that move each link
    /// follow one another, so the last link starts at most `K - 1` passes' moves and `K - 1`
    /// widenings' reach from a suspect's box. (A hundredth more, and a hundredth of the
    /// distance, for rounding.)
    fn moving_reach(&self, config: &SelfCollision) -> f32 {
        let distance = config.distance as f32;
        let pass = 2.0 * config.window as f32 * distance;
        let links = config.grids.saturating_sub(1) as f32;
        links * (pass + self.culling.widening_reach()) * 1.01 + 0.01 * distance
    }

    /// The passes of a step the culling did not clear (`proof`: what it showed; `None` when
    /// the step ran without one).
    fn passes<P: Points + ?Sized>(
        &mut self,
        points: &P,
        weights: &[f32],
        adjacency: &Adjacency,
        config: &SelfCollision,
        proof: Option<Proof>,
        beside: Option<&dyn Beside>,
    ) -> Vec<(u32, Vec3)> {
        let (tried, mut local) = (proof.is_some(), proof == Some(Proof::Local));
        let n = points.count();
        if local {
            self.nearby.begin(n, self.culling.patch_count());
        }
        let mut all_moves = Vec::new();
        let mut copied = false;
        let mut offered = false;
        for k in 0..config.grids {
            local &= offered || self.culling.suspects().len() * self.local_at_most <= n;
            if let Some(beside) = beside.filter(|_| local && k == 0) {
                beside.offer(self.culling.zone(self.moving_reach(config)));
                offered = true;
            }
            let moves = if local {
                self.local_passes += 1;
                let mut watch = Stopwatch::start(self.timing);
                self.nearby
                    .cover(&self.culling, points, config.cell_size as f32);
                self.parts.covering += watch.lap();
                if k == 0 && config.grids > 1 && rayon::current_num_threads() > 1 {
                    self.sort_ahead(config);
                    self.parts.sorting += watch.lap();
                }
                let moves = self.local_pass(weights, adjacency, config, k);
                let mut watch = Stopwatch::start(self.timing);
                let last = k + 1 == config.grids;
                let moves = self.apply_local(moves, points, config.cell_size as f32, last);
                self.parts.moving += watch.lap();
                moves
            } else {
                if !copied {
                    // Every position in mesh order, moved as the local passes so far moved them.
                    let mut watch = Stopwatch::start(self.timing);
                    points.copy_into(&mut self.positions);
                    apply(&mut self.positions, &all_moves);
                    self.parts.covering += watch.lap();
                    copied = true;
                }
                let moves = full_pass(
                    &mut self.binning,
                    &self.positions,
                    weights,
                    adjacency,
                    config,
                    k,
                    self.timing.then_some(&mut self.parts),
                );
                let mut watch = Stopwatch::start(self.timing);
                apply(&mut self.positions, &moves);
                self.parts.moving += watch.lap();
                moves
            };
            all_moves.extend(moves);
        }
        self.nearby.clear();
        self.ahead.clear();
        if tried && local {
            self.backoff = 0;
        } else if tried {
            // A proof that left passes to run in full: the next ones wait, longer each time
            // one fails again.
            self.backoff = (2 * self.backoff).clamp(1, MOST_UNPROVED);
            self.unproved = self.backoff;
        }
        all_moves
    }

    /// Applies a local pass's moves (by slot of the nearby vertices) to the nearby vertices,
    /// and returns them by mesh vertex. Each move counts into its vertex's travel, and every
    /// vertex that has now travelled further than the margin since the proof or since it last
    /// widened the suspects widens them around it (a tenth of the margin is left for
    /// rounding). A widening reaches a margin further than the distance, so a vertex widens
    /// again only after travelling that much more: most vertices that widen go on moving in
    /// the later passes, and widening after every move took a twentieth of a 512^2 step's
    /// self-collision in contact.
    ///
    /// After the `last` pass nothing reads the nearby vertices, their travels or the
    /// suspects a widening adds (the next proof names its own), so its moves are only
    /// renamed: applying them took 6-10 us a step of the 512^2 workload in contact, on one
    /// thread (the earlier passes' 47-64).
    fn apply_local<P: Points + ?Sized>(
        &mut self,
        mut moves: Vec<(u32, Vec3)>,
        points: &P,
        cell_size: f32,
        last: bool,
    ) -> Vec<(u32, Vec3)> {
        if !last {
            let limit = 0.9 * self.culling.margin();
            let reach = nearby::cover_reach(&self.culling, cell_size);
            let culling = &mut self.culling;
            self.nearby.apply(&moves, limit, |point, covers| {
                culling.widen(point, points, reach, covers)
            });
        }
        let vertices = self.nearby.vertices();
        for (slot, _) in &mut moves {
            *slot = vertices[*slot as usize];
        }
        moves
    }

    /// Sorts the nearby vertices by every grid's keys at once, a grid a thread, for the local
    /// passes to repair (see `ahead`): each sort alone runs on one thread.
    fn sort_ahead(&mut self, config: &SelfCollision) {
        let bits = self.local_bits();
        let nearby = &self.nearby;
        self.ahead.sort_all(
            nearby.positions(),
            (nearby.suspects(), nearby.flagged()),
            config.grids,
            |k| GridKeys::with_bits(bits, config, k),
        );
    }

    /// The key bits of a local pass over the nearby vertices.
    fn local_bits(&self) -> u32 {
        (self.local_key_bits)(self.nearby.vertices().len())
    }

    /// Grid `k`'s pass over the nearby vertices, testing the suspects: its moves, by slot of
    /// the nearby vertices.
    fn local_pass(
        &mut self,
        weights: &[f32],
        adjacency: &Adjacency,
        config: &SelfCollision,
        k: u32,
    ) -> Vec<(u32, Vec3)> {
        // Keyed by the low bits of a full pass's keys, as many as the few vertices sorted
        // need (16 at 512^2 instead of 24: two 256-counter digits, not two of 4096). The
        // windows are the same: a run of one key still holds every vertex of the cell, in
        // vertex order, and a window takes only the cell's vertices (see `window_of`). The
        // moves come in this sort's order, not a full pass's; each vertex moves once a pass.
        // Only the vertices that share a key with a suspect are sorted (see `keyed`).
        let nearby = &self.nearby;
        let (vertices, positions) = (nearby.vertices(), nearby.positions());
        let suspects = nearby.suspects();
        let keys = GridKeys::with_bits(self.local_bits(), config, k);
        let moved = nearby.movers().iter().copied();
        let mut watch = Stopwatch::start(self.timing);
        let flags = (suspects, nearby.flagged());
        let sorted = match self.ahead.order(k as usize, positions, flags, moved, &keys) {
            Some(sorted) => sorted,
            None => sorted_with_suspects(
                &mut self.binning,
                &mut self.keyed,
                positions,
                suspects,
                &keys,
            ),
        };
        self.parts.sorting += watch.lap();
        let pass = Pass {
            keys: &keys,
            positions,
            weights,
            adjacency,
            config,
        };
        let moves = pass.moves(
            sorted,
            |slot| vertices[slot as usize],
            |slot| suspects[slot as usize],
        );
        self.parts.window_tests += watch.lap();
        moves
    }

    /// A resolver for `model` that groups its vertices as its scene placed them, or along
    /// the surface where it placed them in folds ([`patch_order`]; `places` are the vertices
    /// in the order their positions' owner keeps them, see [`Points::place`]).
    pub fn grouped_by(model: &Model, places: &[u32]) -> Self {
        let mut resolver = Self::default();
        resolver.culling.group_in_order(patch_order(model, places));
        resolver
    }

    /// Groups the vertices as they lie in `layout` (see [`Culling::group_by`]).
    pub fn group_by(&mut self, layout: &[Vec3]) {
        self.culling.group_by(layout);
    }

    /// Whether the next steps time their parts ([`Resolver::part_times`]); off at first.
    pub fn time_parts(&mut self, on: bool) {
        self.timing = on;
        self.culling.timing = on;
    }

    /// Where the last step's self-collision spent its time (zeros unless timed).
    pub fn part_times(&self) -> PartTimes {
        self.parts
    }

    /// The culling, with its counts of steps cleared and not.
    pub fn culling(&self) -> &Culling {
        &self.culling
    }

    /// Passes that tested only the culling's suspect vertices.
    pub fn local_passes(&self) -> u64 {
        self.local_passes
    }

    /// Steps run without a proof, after proofs that did not help.
    pub fn unproved_steps(&self) -> u64 {
        self.unproved_steps
    }
}

/// [`resolve`] with sort buffers kept from one step to the next.
fn resolve_with(
    binning: &mut Binning,
    positions: &mut [Vec3],
    weights: &[f32],
    adjacency: &Adjacency,
    config: &SelfCollision,
) -> Vec<(u32, Vec3)> {
    let mut all_moves = Vec::new();
    for k in 0..config.grids {
        let moves = full_pass(binning, positions, weights, adjacency, config, k, None);
        apply(positions, &moves);
        all_moves.extend(moves);
    }
    all_moves
}

/// Grid `k`'s pass over every vertex: its moves, not yet applied. Its sorting and window
/// tests are added to `parts`, if given.
fn full_pass(
    binning: &mut Binning,
    positions: &[Vec3],
    weights: &[f32],
    adjacency: &Adjacency,
    config: &SelfCollision,
    k: u32,
    mut parts: Option<&mut PartTimes>,
) -> Vec<(u32, Vec3)> {
    let keys = GridKeys::new(positions.len(), config, k);
    let mut watch = Stopwatch::start(parts.is_some());
    let sorted = sorted_for_grid(binning, positions, &keys);
    if let Some(parts) = parts.as_deref_mut() {
        parts.sorting += watch.lap();
    }
    let pass = Pass {
        keys: &keys,
        positions,
        weights,
        adjacency,
        config,
    };
    let moves = pass.moves(sorted, |v| v, |_| true);
    if let Some(parts) = parts {
        parts.window_tests += watch.lap();
    }
    moves
}

/// What one grid's pass tests its windows with.
struct Pass<'a> {
    keys: &'a GridKeys,
    /// The positions of the sorted entries, by entry index.
    positions: &'a [Vec3],
    weights: &'a [f32],
    adjacency: &'a Adjacency,
    config: &'a SelfCollision,
}

impl Pass<'_> {
    /// The moves, in sorted order, each by the entry's index in [`Pass::positions`]: each
    /// entry of `sorted` that `tested` names pushed away from the unjoined vertices of its
    /// window closer than the distance. `vertex` gives an entry's mesh vertex.
    fn moves(
        &self,
        sorted: &[Entry],
        vertex: impl Fn(u32) -> u32 + Sync,
        tested: impl Fn(u32) -> bool + Sync,
    ) -> Vec<(u32, Vec3)> {
        let (distance, positions) = (self.config.distance as f32, self.positions);
        // Most vertices are alone in their cell: only those with a same-key neighbour in
        // sorted order ("crowded") are looked at, and only nonzero moves are kept.
        let task_len = window_task(sorted.len());
        (0..sorted.len().div_ceil(task_len))
            .into_par_iter()
            .flat_map_iter(|task| {
                let slots = task * task_len..((task + 1) * task_len).min(sorted.len());
                // Checked before touching the vertex: its data sits at a random address.
                let crowded = crowded_slots(slots, sorted, &tested);
                let mut moves = Vec::new();
                for (i, &j) in crowded.iter().enumerate() {
                    // A crowded slot's window holds only crowded slots, so fetching each
                    // one's position ahead of time covers most of the window.
                    if let Some(&ahead) = crowded.get(i + PREFETCH_AHEAD) {
                        prefetch(&positions[vertex_of(sorted[ahead]) as usize]);
                    }
                    let e = vertex_of(sorted[j]);
                    let (xp, p) = (positions[e as usize], vertex(e));
                    let mut correction = Vec3::ZERO;
                    for f in window_of(j, self.config.window, sorted, positions, self.keys) {
                        let d = xp - positions[f as usize];
                        correction +=
                            push(self.adjacency, self.weights, distance, [p, vertex(f)], d);
                    }
                    // A pinned vertex does not move (its weight is read only now: most
                    // vertices have no close pair).
                    if correction != Vec3::ZERO && self.weights[p as usize] > 0.0 {
                        moves.push((e, correction));
                    }
                }
                moves
            })
            .collect()
    }
}

fn apply(positions: &mut [Vec3], moves: &[(u32, Vec3)]) {
    for &(p, c) in moves {
        positions[p as usize] += c;
    }
}

/// How far `p` moves away from `q`, `d` running from `q` to `p` (zero unless they are unjoined
/// and too close): `p`'s share of the push, by inverse mass. The weights are read only for a
/// close pair: most window pairs are not, and weights sit at random addresses.
fn push(adjacency: &Adjacency, weights: &[f32], distance: f32, [p, q]: [u32; 2], d: Vec3) -> Vec3 {
    let l2 = d.dot(d);
    if l2 >= distance * distance || joined(adjacency, p, q) {
        return Vec3::ZERO;
    }
    let (wp, wq) = (weights[p as usize], weights[q as usize]);
    let share = wp / (wp + wq);
    if l2 == 0.0 {
        // Coincident: part them vertically, the lower index going up.
        let sign = if p < q { 1.0 } else { -1.0 };
        return Vec3::Y * (sign * share * distance);
    }
    let l = l2.sqrt();
    d * (share * (distance - l) / l)
}

/// Unordered pair `(low, high)`.
fn pair(a: u32, b: u32) -> (u32, u32) {
    (a.min(b), a.max(b))
}

/// The pairs the binning finds (detection only, every grid on the same positions), sorted.
pub fn approximate_pairs(
    positions: &[Vec3],
    adjacency: &Adjacency,
    config: &SelfCollision,
) -> Vec<(u32, u32)> {
    let distance = config.distance as f32;
    let mut binning = Binning::default();
    let mut pairs: Vec<(u32, u32)> = (0..config.grids)
        .flat_map(|k| {
            let keys = GridKeys::new(positions.len(), config, k);
            let sorted = sorted_for_grid(&mut binning, positions, &keys);
            let mut found = Vec::new();
            for (j, &entry) in sorted.iter().enumerate() {
                let p = vertex_of(entry);
                for q in window_of(j, config.window, sorted, positions, &keys) {
                    if p < q && close_and_unjoined(positions, adjacency, distance, p, q) {
                        found.push((p, q));
                    }
                }
            }
            found
        })
        .collect();
    pairs.sort_unstable();
    pairs.dedup();
    pairs
}

fn close_and_unjoined(
    positions: &[Vec3],
    adjacency: &Adjacency,
    distance: f32,
    a: u32,
    b: u32,
) -> bool {
    positions[a as usize].distance_squared(positions[b as usize]) < distance * distance
        && !joined(adjacency, a, b)
}

/// Every unjoined pair closer than `distance`, exactly: a hash grid of cells `distance` wide
/// searched over each point's 27 neighbouring cells. Sorted.
pub fn exact_pairs(positions: &[Vec3], adjacency: &Adjacency, distance: f64) -> Vec<(u32, u32)> {
    let inverse_cell = (1.0 / distance) as f32;
    let mut cells: HashMap<IVec3, Vec<u32>> = HashMap::new();
    for (v, &p) in positions.iter().enumerate() {
        cells
            .entry(cell_of(p, inverse_cell, 0.0))
            .or_default()
            .push(v as u32);
    }
    let distance = distance as f32;
    let mut pairs: Vec<(u32, u32)> = (0..positions.len() as u32)
        .into_par_iter()
        .flat_map_iter(|a| {
            let home = cell_of(positions[a as usize], inverse_cell, 0.0);
            let mut found = Vec::new();
            for dz in -1..=1 {
                for dy in -1..=1 {
                    for dx in -1..=1 {
                        let Some(members) = cells.get(&(home + IVec3::new(dx, dy, dz))) else {
                            continue;
                        };
                        for &b in members {
                            if a < b && close_and_unjoined(positions, adjacency, distance, a, b) {
                                found.push(pair(a, b));
                            }
                        }
                    }
                }
            }
            found
        })
        .collect();
    pairs.sort_unstable();
    pairs
}

/// Every unjoined pair closer than `distance` by testing all pairs (the exact search's oracle).
pub fn brute_force_pairs(
    positions: &[Vec3],
    adjacency: &Adjacency,
    distance: f64,
) -> Vec<(u32, u32)> {
    let n = positions.len() as u32;
    let distance = distance as f32;
    (0..n)
        .flat_map(|a| (a + 1..n).map(move |b| (a, b)))
        .filter(|&(a, b)| close_and_unjoined(positions, adjacency, distance, a, b))
        .collect()
}

/// Mean vertices per occupied cell of `config`'s first grid (how crowded the cells are).
pub fn vertices_per_cell(positions: &[Vec3], config: &SelfCollision) -> f64 {
    let inverse_cell = (1.0 / config.cell_size) as f32;
    let mut cells: Vec<IVec3> = positions
        .iter()
        .map(|&p| cell_of(p, inverse_cell, 0.0))
        .collect();
    cells.sort_unstable_by_key(|c| (c.x, c.y, c.z));
    cells.dedup();
    positions.len() as f64 / cells.len().max(1) as f64
}

/// Share of `exact` pairs missing from `found` (both sorted); zero when there are none.
pub fn missed_share(exact: &[(u32, u32)], found: &[(u32, u32)]) -> f64 {
    if exact.is_empty() {
        return 0.0;
    }
    let missed = exact
        .iter()
        .filter(|p| found.binary_search(p).is_err())
        .count();
    missed as f64 / exact.len() as f64
}

/// A pool of `threads` threads, for the tests that run the same work on several pool sizes.
#[cfg(test)]
fn pool_of(threads: usize) -> rayon::ThreadPool {
    rayon::ThreadPoolBuilder::new()
        .num_threads(threads)
        .build()
        .expect("pool")
}

#[cfg(test)]
mod tests {
    use super::*;
    use rand::{RngExt, SeedableRng};

    fn no_springs(n: usize) -> Adjacency {
        Adjacency::from_springs(n, &[])
    }

    fn random_cloud(n: usize, seed: u64) -> Vec<Vec3> {
        let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(seed);
        (0..n)
            .map(|_| Vec3::new(rng.random(), rng.random::<f32>() * 0.3, rng.random()))
            .collect()
    }

    #[test]
    fn exact_search_equals_brute_force() {
        for (seed, distance) in [(1, 0.03), (2, 0.05), (3, 0.11)] {
            let points = random_cloud(1500, seed);
            // Join some near pairs by springs: they must be left out by both.
            let ends: Vec<[u32; 2]> = (0..200).map(|i| [2 * i, 2 * i + 1]).collect();
            let adjacency = Adjacency::from_springs(points.len(), &ends);
            let exact = exact_pairs(&points, &adjacency, distance);
            assert!(
                exact.len() > 50,
                "the test needs pairs, found {}",
                exact.len()
            );
            assert_eq!(exact, brute_force_pairs(&points, &adjacency, distance));
        }
    }

    #[test]
    fn sort_is_stable_and_ordered() {
        let keys = [5, 1, 5, 0, 1, 5];
        let (sorted, order) = sort_by_key(&keys);
        assert_eq!(sorted, [0, 1, 1, 5, 5, 5]);
        assert_eq!(order, [3, 1, 4, 0, 2, 5]);
    }

    #[test]
    fn more_grids_miss_fewer_pairs() {
        let points = random_cloud(4000, 7);
        let adjacency = no_springs(points.len());
        let config = |grids| SelfCollision {
            distance: 0.03,
            cell_size: 0.06,
            grids,
            window: 8,
        };
        let exact = exact_pairs(&points, &adjacency, 0.03);
        let one = missed_share(&exact, &approximate_pairs(&points, &adjacency, &config(1)));
        let four = missed_share(&exact, &approximate_pairs(&points, &adjacency, &config(4)));
        // One grid misses every pair split by a cell face; staggered grids recover most.
        assert!(one > 0.2, "one grid missed {one}");
        assert!(four < one / 2.0, "four grids missed {four}, one {one}");
        // Found pairs are real pairs.
        let found = approximate_pairs(&points, &adjacency, &config(4));
        assert!(found.iter().all(|p| exact.binary_search(p).is_ok()));
    }

    /// A close pair whose vertex numbers lie around `window` vertices of a far cell hashed to
    /// the same key: the far vertices take no place in the pair's windows, so it is found.
    #[test]
    fn far_cells_hashed_alike_take_no_place_in_a_window() {
        let config = SelfCollision {
            distance: 0.04,
            cell_size: 0.1,
            grids: 1,
            window: 3,
        };
        let n = 2 + config.window as usize;
        let bits = key_bits(n);
        let home = IVec3::new(2, 0, 2);
        let far = (1..)
            .map(|i| home + IVec3::new(i, 0, 0))
            .find(|&cell| cell_key(cell, bits) == cell_key(home, bits))
            .expect("a cell hashed alike");
        assert!(far.x - home.x > 1, "{far}");
        let centre = |cell: IVec3| (cell.as_vec3() + 0.5) * config.cell_size as f32;
        // Vertex 0 and the last are the pair, in the home cell; the others share the far cell.
        let mut points: Vec<Vec3> = (0..n)
            .map(|i| centre(far) + Vec3::X * 0.001 * i as f32)
            .collect();
        points[0] = centre(home);
        points[n - 1] = centre(home) + Vec3::new(0.01, 0.0, 0.0);
        let adjacency = no_springs(n);
        let found = approximate_pairs(&points, &adjacency, &config);
        assert!(found.contains(&(0, n as u32 - 1)), "{found:?}");
        let mut moved = points.clone();
        let moves = resolve(&mut moved, &vec![1.0; n], &adjacency, &config);
        assert!(moved[0].distance(moved[n - 1]) > 0.0399, "{moves:?}");
    }

    #[test]
    fn resolving_parts_close_pairs_and_leaves_pins_and_springs() {
        let points = vec![
            Vec3::ZERO,
            Vec3::new(0.01, 0.0, 0.0),
            Vec3::new(0.0, 0.0, 0.015),
            Vec3::new(5.0, 0.0, 0.0),
        ];
        // Vertex 2 is pinned; vertices 0 and 2 are joined by a spring.
        let adjacency = Adjacency::from_springs(4, &[[0, 2]]);
        let weights = [1.0, 1.0, 0.0, 1.0];
        let config = SelfCollision {
            distance: 0.04,
            cell_size: 0.1,
            grids: 1,
            window: 3,
        };
        let mut moved = points.clone();
        let mut deltas = [Vec3::ZERO; 4];
        for (v, c) in resolve(&mut moved, &weights, &adjacency, &config) {
            deltas[v as usize] += c;
        }
        // 0 and 1 share the push equally; 1 also leaves pinned 2 by itself.
        assert_eq!(moved[2], points[2]);
        assert!(moved[0].distance(moved[1]) > 0.035);
        assert!(moved[1].distance(moved[2]) > 0.0399);
        assert_eq!(moved[3], points[3]);
        for v in 0..4 {
            assert!((deltas[v] - (moved[v] - points[v])).length() < 1e-7);
        }
    }

    #[test]
    fn floor_is_the_float_floor_and_defined_for_any_float() {
        let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(11);
        let mut values = vec![0.0, -0.0, 1.0, -1.0, 0.5, -0.5, 1e-30, -1e-30, 1.999_999_9];
        values.extend((0..10_000).map(|_| rng.random_range(-3e4f32..3e4)));
        values.extend([-1.9e9, 1.9e9, -16_777_217.0, 8_388_608.5]);
        for x in values {
            assert_eq!(floor(x), x.floor() as i32, "{x}");
        }
        // Far out and not a number: clamped to +-2e9 (never a panic or undefined behaviour).
        assert_eq!(floor(f32::NAN), -2_000_000_000);
        assert_eq!(floor(f32::INFINITY), 2_000_000_000);
        assert_eq!(floor(-3e9), -2_000_000_000);
    }

    #[test]
    fn keys_are_the_same_bits_with_avx2_as_without() {
        let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(12);
        let mut points: Vec<Vec3> = (0..10_000)
            .map(|_| Vec3::from_array(std::array::from_fn(|_| rng.random_range(-50.0..50.0))))
            .collect();
        // Cell faces, far out, and not finite.
        points.extend([
            Vec3::ZERO,
            Vec3::splat(-0.0),
            Vec3::new(0.02, -0.02, 0.04),
            Vec3::splat(3e9),
            Vec3::new(f32::NAN, f32::INFINITY, f32::NEG_INFINITY),
        ]);
        let config = SelfCollision {
            distance: 0.01,
            cell_size: 0.02,
            grids: 4,
            window: 4,
        };
        for k in 0..config.grids {
            let keys = GridKeys::new(points.len(), &config, k);
            let mut plain = vec![0; points.len()];
            keys.batch(&points, &mut plain);
            let mut widened = vec![0; points.len()];
            wide::wide(
                #[inline(always)]
                || keys.batch(&points, &mut widened),
            );
            assert_eq!(plain, widened, "grid {k}");
            assert_eq!(plain[0], keys.of(points[0]));
        }
    }

    #[test]
    fn key_bits_cover_twice_the_points_in_whole_bytes() {
        assert_eq!(key_bits(10), 8);
        assert_eq!(key_bits(4096), 16);
        assert_eq!(key_bits(40_000), 24);
        assert_eq!(key_bits(262_144), 24);
    }
}
