//! A proof, renewed every step, that no unjoined pair of vertices is closer than the
//! self-collision distance. When it holds, every grid's pass would find nothing to push, so
//! the passes are skipped and the step gives the same bits; when it fails anywhere, they run.
//!
//! Vertices are grouped into patches of up to [`PATCH`], close together in the layout the owner
//! gives ([`Culling::group_by`]: the mesh as its scene placed it; [`Culling::group_in_order`]:
//! pieces of its surface, see `along_surface`), or else where they were first seen (Morton
//! order of those positions), and the patches are numbered in the order of the owner's memory
//! (see [`Culling::build`]). Each patch keeps reference positions `R_i`, taken
//! when its shape was last renewed. Each step its vertices' displacements `u_i = x_i - R_i` are
//! split into a centre `c_P` and a remainder of at most `E_P`; any centre will do, and the
//! measurement takes the centre of the displacements' box (`E_P` half its diagonal). So for
//! `i` in `P` and `j` in `Q`
//!
//! ```text
//! |x_i - x_j| >= |(R_i + c_P) - (R_j + c_Q)| - E_P - E_Q.
//! ```
//!
//! A patch renews its references when `E_P` grows past an eighth of its slack (it bends or
//! turns); a pure translation costs nothing.
//!
//! - **Near pairs** (patches within two springs of each other on the mesh, and each patch
//!   with itself) keep the smallest unjoined `|(R_i + c_P) - (R_j + c_Q)|` when it was last
//!   measured, `g_PQ`, and the `c_P - c_Q` of then. The first term above can only have shrunk
//!   by how far `c_P - c_Q` has moved since, so the pair is clear while
//!   `g_PQ - |Δ(c_P - c_Q)| - E_P - E_Q >= distance + margin`. Otherwise `g_PQ` is measured
//!   again, and failing that, the vertices themselves.
//! - **Far pairs** are clear when their bounding boxes lie further apart than the distance
//!   along some axis: a bounding volume hierarchy over the patches (halving their Morton
//!   order, refitted each step) finds the few that do not, whose vertices are then measured,
//!   and which are then kept as near pairs until their boxes part. Each step the search goes
//!   on from the pairs of nodes where it stopped the step before.
//!
//! When some pair is closer than the distance, the proof still names the vertices it failed
//! for, measured against the distance plus a margin ([`MARGIN`] of it): in each pair of
//! patches that does not clear that, the vertices within it of an unjoined vertex of the
//! other patch ("suspects"). Every other vertex ("cleared") is at least that far from every
//! unjoined vertex, so no pass can push it until the passes' moves add up to the margin
//! (`Resolver` then tests only the suspects).
//!
//! Verlet neighbour lists (a skin around each particle, rebuilt when particles have moved
//! further than it) work the same way; the patches make a falling or swinging sheet, whose
//! vertices all move far but together, cost nothing more than one at rest. Everything is
//! float32 with a margin that covers its rounding, and any non-finite position fails the proof.

use std::sync::Arc;
use std::time::Duration;

use glam::{DVec3, Vec3, Vec4};
use rayon::prelude::*;

use super::LANES;
use super::wide::wide;
use super::{Points, Stopwatch, prefetch, prefetch_lines};
use crate::Adjacency;

/// Most vertices in one patch (an 8 x 8 block of a grid).
pub const PATCH: usize = 64;

/// The margin beyond the distance within which a pair makes its patches suspect, as a share
/// of the distance. Smaller, fewer patches are suspect (fewer vertices covered, sorted and
/// tested), but more vertices are pushed past it and widen the suspects. It also bounds the
/// zone the next step begins beside the passes outside of, so a smaller one leaves more of
/// that step to begin early. A sixteenth since 2026-12-07: on an Intel Xeon VM, the bench's
/// 512^2 sheet in contact stepped 1-10% faster by gather and 2-8% by scatter than with an
/// eighth (windows of 200 steps, the two alternating within one run), and `hooke bench`'s
/// paired ratio at 512^2 by gather read medians of 2.685 against 3.045 and 2.795 against
/// 2.865 in two batches (six and eight runs each; by scatter the bench showed nothing either
/// way). A thirty-second stepped 1-4% faster again within a run, but read 2.84 in the first
/// batch. An eighth since 2026-12-03, a quarter before (see the performance log). The proof
/// holds for any margin, so the moves are the same.
pub const MARGIN: f32 = 0.0625;

/// What [`Culling::prove`] showed of one step's positions.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Proof {
    /// No unjoined pair is closer than the distance: the passes would move nothing.
    Clear,
    /// Some may be, but only vertices of [`Culling::suspects`] are closer than the distance
    /// plus [`Culling::margin`] to an unjoined vertex.
    Local,
    /// Nothing (a position is not finite).
    Nothing,
}

/// A patch's points by axis, `PATCH` slots each; the slots past a short last patch's members
/// repeat its first, so whole-patch loops need no count and their extremes are unchanged.
type Frame = [[f32; PATCH]; 3];

/// Patches per subtree below which the hierarchy is searched on the calling thread.
const PARALLEL_PATCHES: u32 = 64;

/// Patches per subtree below which `refit` fits the boxes on the calling thread: 8 tasks at
/// 512^2 (4,096 patches).
const REFIT_TASK_PATCHES: u32 = 512;

/// A patch: its state this step and since its references were taken.
#[derive(Clone, Copy, Debug)]
struct Patch {
    /// `c_P`: centre of the displacements' bounding box, m.
    centre: Vec3,
    /// `E_P`: half the diagonal of the displacements' box, m: no displacement lies farther from
    /// `centre`.
    spread: f32,
    /// The sum of `c_P` at every renewal of the references, m: `shift + centre` is where the
    /// patch has moved since it was built, in the frame every cached gap is kept in.
    shift: DVec3,
    /// The sum of `E_P` at every renewal, m: how much the renewals may have cost the cached
    /// gaps of its near pairs.
    renewed: f64,
    /// The smallest `g_PQ` over its near pairs measured since the references were taken, m,
    /// and the one before they were last taken (what sets when they are renewed).
    closest: f32,
    earlier_closest: f32,
    /// The references' largest coordinate, m, kept from when they were taken (infinite if one
    /// is not finite: they are then renewed).
    reference_scale: f32,
    /// The references' bounding box, m, kept from when they were taken.
    reference_low: Vec3,
    reference_high: Vec3,
    /// A box around the current positions, m: the references' box moved by the
    /// displacements' (see [`measure_patch_with`]).
    low: Vec3,
    high: Vec3,
}

impl Patch {
    /// `shift + centre`, m.
    fn moved(&self) -> DVec3 {
        self.shift + self.centre.as_dvec3()
    }
}

/// What the near pairs' cached gaps need of a patch each step: 32 bytes, kept apart from the
/// cache lines of its [`Patch`], of which each of the 20,000 near pairs of a 512^2 sheet
/// reads two every step.
#[derive(Clone, Copy, Debug, Default)]
struct Standing {
    /// [`Patch::moved`], m.
    moved: DVec3,
    /// [`Patch::renewed`] and [`Patch::spread`]: how much of a gap cached since the patch was
    /// built its renewals and its spread now may have taken, m.
    taken: f64,
}

impl Standing {
    fn of(patch: &Patch) -> Self {
        Self {
            moved: patch.moved(),
            taken: patch.renewed + f64::from(patch.spread),
        }
    }
}

/// A pair of near patches and what was measured of it: 32 bytes, two to a cache line, as the
/// cached gaps' pass reads every one every step (56 bytes before, with the gap, the renewals
/// and the offset apart and in f64).
#[derive(Clone, Copy, Debug)]
struct NearPair {
    patches: [u32; 2],
    /// `g_PQ` plus the patches' `renewed` when it was measured, less what rounding `offset`
    /// may have cost, m (minus infinity until measured): less their `renewed` now, what
    /// their renewals since have left of the gap.
    budget: f64,
    /// The patches' `shift + centre`, P's less Q's, when `g_PQ` was measured, m, rounded to
    /// f32 (by a 2^-24th of its length at most, which `budget` allows for).
    offset: Vec3,
    /// Whether the pair was within the distance plus the margin when last checked.
    suspect: bool,
}

impl NearPair {
    /// Patches `p` and `q` (`p <= q`), not yet measured.
    fn unmeasured(patches: [u32; 2]) -> Self {
        Self {
            patches,
            budget: f64::NEG_INFINITY,
            offset: Vec3::ZERO,
            suspect: false,
        }
    }

    /// Caches `gap`, measured with the patches at `offset` (their `shift + centre`, P's less
    /// Q's) and `renewed` their `renewed`.
    fn measured(&mut self, gap: f32, offset: DVec3, renewed: [f64; 2]) {
        let rounded = offset.as_vec3();
        // A 2^-24th of the offset for its rounding, and as much again for the sum's.
        let rounding = f64::from(rounded.length()) * 1.2e-7 + 1e-12;
        self.offset = rounded;
        self.budget = f64::from(gap) + renewed[0] + renewed[1] - rounding;
    }
}

/// Due near pairs a task measures, each asking for the next one's lines.
const DUE_TASK: usize = 16;

/// Proofs between looks for adopted pairs whose patches have parted.
const PARTING_EVERY: u64 = 16;

/// How far apart an adopted pair's boxes must be, as a multiple of the distance plus the
/// margin, before it is given back to the far search; between that and once (where the far
/// search would find it again), a pair that wavers is not given back and adopted by turns.
const PARTED: f32 = 2.0;

/// How far the far search's stops may grow, as a multiple of the patches (or of their number
/// after the last walk from the hierarchy's root, if more), before it walks from the root again.
const REWALK_GROWTH: usize = 8;

/// Pairs of patches found suspect, each with its suspect vertices where they were named
/// while it was checked.
type SuspectPairs = Vec<([u32; 2], Option<[Close; 2]>)>;

/// What measuring a near pair showed: what it found, the pair's gap if it was measured
/// again, and its suspect vertices if they were named.
type Measured = (Found, Option<f32>, Option<[Close; 2]>);

/// A node of the hierarchy over the patches at `first..end` of their Morton order; a leaf's
/// `first` is its patch (and `end` one more).
#[derive(Clone, Copy, Debug)]
struct Node {
    first: u32,
    end: u32,
    /// Indices of the two halves, `None` for a single patch.
    children: Option<[u32; 2]>,
    low: Vec3,
    high: Vec3,
}

impl Node {
    /// How far its box lies from `other`'s (see [`box_gap`]).
    fn gap(&self, other: &Node) -> f32 {
        box_gap((self.low, self.high), (other.low, other.high))
    }

    /// The smallest box holding its box and `other`'s.
    fn hull(&self, other: &Node) -> (Vec3, Vec3) {
        (self.low.min(other.low), self.high.max(other.high))
    }
}

/// Fits the boxes of the subtree whose root is `nodes[0]`, at `offset` in the whole hierarchy,
/// around its patches' `boxes`. The nodes are in depth-first order, so a subtree's are a run
/// (the root, then its first half's, then its second's) and every node comes before its
/// children: one pass from the last node to the first fits each after its children. Subtrees
/// of [`REFIT_TASK_PATCHES`] or more fit their halves side by side. (Recursing down to every
/// leaf with a join at each subtree of 64 patches or more, reading each leaf's box from its
/// 112-byte [`Patch`] in the hierarchy's order, took 21-74 us a step at 512^2 on 2 threads in
/// contact, against 10-42 this way; see the performance log.)
fn refit(nodes: &mut [Node], offset: usize, boxes: &[(Vec3, Vec3)]) {
    let Some((root, rest)) = nodes.split_first_mut() else {
        return;
    };
    if let Some([a, b]) = root.children
        && root.end - root.first >= REFIT_TASK_PATCHES
    {
        let (a, b) = (a as usize, b as usize);
        let (first, second) = rest.split_at_mut(b - a);
        rayon::join(|| refit(first, a, boxes), || refit(second, b, boxes));
        (root.low, root.high) = first[0].hull(&second[0]);
        return;
    }
    for i in (0..nodes.len()).rev() {
        let (low, high) = match nodes[i].children {
            None => boxes[nodes[i].first as usize],
            Some([a, b]) => nodes[a as usize - offset].hull(&nodes[b as usize - offset]),
        };
        (nodes[i].low, nodes[i].high) = (low, high);
    }
}

/// The culling's state, kept by a solver from one step to the next.
#[derive(Debug, Default)]
pub struct Culling {
    /// Vertex count and adjacency entries it was built for.
    built_for: (usize, usize),
    /// Every vertex, in an order whose runs of `PATCH` are the patches, if given.
    order: Vec<u32>,
    /// Every vertex, patch after patch (`PATCH` slots each, the last one shorter).
    members: Vec<u32>,
    /// Where the positions' owner keeps each of `members` ([`Points::place`]); shared with
    /// the step's [`Zone`].
    places: Arc<[u32]>,
    /// `R_i`, a frame per patch.
    references: Vec<Frame>,
    /// Where each patch's 8 rows start, if its members fill 8 of the owner's blocks
    /// ([`Points::lanes`]): the patch is then measured from where they lie. Kept apart from
    /// `places`, which the measurement would otherwise read in full for these 8 numbers (256
    /// bytes a patch, a third as many as its points; at 512^2 measuring took a tenth longer).
    block_starts: Vec<Option<[u32; PATCH / LANES]>>,
    /// Each vertex's slot in `members` (its patch's, and its place in the patch).
    slot_of: Vec<u32>,
    /// Each slot of `members`' neighbours, as slots of `members` (rows of a CSR table): a
    /// patch's rows lie together, where the adjacency's are spread over the mesh.
    joined_offsets: Vec<u32>,
    joined: Vec<u32>,
    patches: Vec<Patch>,
    /// Each patch's [`Standing`] this step.
    standings: Vec<Standing>,
    /// Each patch's box this step ([`Patch::low`], [`Patch::high`]), 24 bytes a patch for
    /// `refit` to read in the hierarchy's order.
    boxes: Vec<(Vec3, Vec3)>,
    /// The near pairs: first those that springs join (two springs at most, fixed when
    /// built), then those adopted from the far search.
    near: Vec<NearPair>,
    /// Each patch's near patches that springs join, sorted (rows of a CSR table); shared
    /// with the step's [`Zone`].
    near_offsets: Arc<[u32]>,
    near_patches: Arc<[u32]>,
    /// How many of `near` springs join; the rest are adopted.
    joined_pairs: usize,
    /// Each patch's adopted near patches numbered above it (a pair is listed under its
    /// lower patch).
    adopted: Vec<Vec<u32>>,
    /// Proofs so far.
    proofs: u64,
    /// Pairs of the hierarchy's nodes that together hold every pair of patches that is not
    /// near, each pair of patches under one of them: see [`Culling::far_pairs`].
    frontier: Vec<[u32; 2]>,
    /// How long `frontier` was after the last walk of the whole hierarchy; `None` until one.
    walked: Option<usize>,
    /// Walks of the whole hierarchy so far.
    pub walks: u64,
    /// Each patch's leaf in `nodes`.
    leaf_of: Vec<u32>,
    /// The hierarchy, root first, every node before its children.
    nodes: Vec<Node>,
    /// The last proof's suspect vertices: each patch's (a bit per slot, and the box they lay
    /// in), the patches in the order they gained some, and the vertices.
    suspect_closes: Vec<Close>,
    suspect_list: Vec<u32>,
    suspects: Vec<u32>,
    /// The last proof's margin, and the distance at which a pair was clear, m.
    margin: f32,
    clear_at: f32,
    /// Steps cleared, and steps whose passes had to run.
    pub cleared: u64,
    pub uncleared: u64,
    /// Patches that [`Culling::widen`] made vertices of suspect, once a widening.
    pub widened: u64,
    /// How long the last proof took to measure the patches (and to build itself, when it
    /// did): the rest of it went to the pairs of patches. Zero unless `timing`.
    measuring: Duration,
    pub(super) timing: bool,
}

/// The vertices a step's local passes may move, and those springs join to them, as found
/// right after the proof ([`Culling::zone`]): its owner may meanwhile work on the others, which
/// stay where they are for the whole step, and whose neighbours do too.
#[derive(Debug)]
pub struct Zone {
    /// Boxes around the suspects at the proof, and how far from them a vertex the passes
    /// move may lie.
    groups: Vec<(Vec3, Vec3)>,
    reach: f32,
    /// Patches that may hold a vertex the passes move: those whose boxes come within
    /// `reach` of one of `groups`.
    moving: Vec<u32>,
    places: Arc<[u32]>,
    near_offsets: Arc<[u32]>,
    near_patches: Arc<[u32]>,
}

impl Zone {
    /// Whether `point` lies within the reach of the suspects' boxes (along every axis), as
    /// every vertex the passes may move did at the proof.
    pub fn reaches(&self, point: Vec3) -> bool {
        self.groups
            .iter()
            .any(|&(low, high)| box_gap((low, high), (point, point)) < self.reach)
    }

    /// Calls `each` with the place ([`Points::place`]) of every vertex of the patches that
    /// may hold one the passes move, and of the patches within two springs of those: every
    /// vertex they may move, every vertex a spring joins to one, and some more. Each place
    /// once.
    pub fn each_place(&self, mut each: impl FnMut(u32)) {
        let mut seen = vec![false; self.near_offsets.len().saturating_sub(1)];
        for &p in &self.moving {
            let row =
                self.near_offsets[p as usize] as usize..self.near_offsets[p as usize + 1] as usize;
            for &q in &self.near_patches[row] {
                if !std::mem::replace(&mut seen[q as usize], true) {
                    let first = q as usize * PATCH;
                    let last = (first + PATCH).min(self.places.len());
                    self.places[first..last]
                        .iter()
                        .for_each(|&place| each(place));
                }
            }
        }
    }
}

/// What a check found of some pairs: whether one is within the distance plus the margin
/// (its patches are suspect), and whether one is within the distance.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
struct Found {
    suspect: bool,
    contact: bool,
}

impl Found {
    /// What a closest unjoined distance shows.
    fn at<P: ?Sized>(closest: f32, check: &Check<P>) -> Self {
        Self {
            suspect: closest < check.suspect_at,
            contact: closest < check.clear_at,
        }
    }
}

/// Vertices of one patch that a pair of patches makes suspect: a bit per slot, and the box
/// of their positions.
#[derive(Clone, Copy, Debug)]
struct Close {
    bits: u64,
    low: Vec3,
    high: Vec3,
}

impl Close {
    const NONE: Self = Self {
        bits: 0,
        low: Vec3::INFINITY,
        high: Vec3::NEG_INFINITY,
    };

    /// Adds slot `k`, at `x`.
    fn add(&mut self, k: usize, x: Vec3) {
        self.bits |= 1 << k;
        (self.low, self.high) = (self.low.min(x), self.high.max(x));
    }

    fn join(&mut self, other: Self) {
        self.bits |= other.bits;
        (self.low, self.high) = (self.low.min(other.low), self.high.max(other.high));
    }
}

/// The first `count` slots of `frame` closer to `x` than `within.sqrt()`, a bit each.
fn slots_within(frame: &Frame, count: usize, x: Vec3, within: f32) -> u64 {
    let bits = (0..PATCH / 8).fold(0, |bits, r| {
        bits | row_within(frame, r, x, within) << (8 * r)
    });
    bits & (u64::MAX >> (PATCH - count))
}

/// The slots of row `r` of `frame` (slots `8 r..8 r + 8`) closer to `x` than `within.sqrt()`,
/// a bit each from the lowest.
#[inline(always)]
fn row_within(frame: &Frame, r: usize, x: Vec3, within: f32) -> u64 {
    under(row_squared(frame, r, x), within)
}

/// The squared distances of row `r`'s slots of `frame` from `x`, four lanes at a time.
#[inline(always)]
fn row_squared(frame: &Frame, r: usize, x: Vec3) -> [Vec4; 2] {
    let four = |first: usize| {
        let axis = |a: usize| Vec4::from_slice(&frame[a][first..first + 4]);
        let d = [
            axis(0) - Vec4::splat(x.x),
            axis(1) - Vec4::splat(x.y),
            axis(2) - Vec4::splat(x.z),
        ];
        d[0] * d[0] + d[1] * d[1] + d[2] * d[2]
    };
    [four(8 * r), four(8 * r + 4)]
}

/// The lanes of a row's squared distances below `limit`, a bit each from the lowest: each
/// comparison's lanes taken as bits at once (a slot at a time, the naming of suspects took
/// half as long again at 512^2).
#[inline(always)]
fn under([low, high]: [Vec4; 2], limit: f32) -> u64 {
    let limit = Vec4::splat(limit);
    u64::from(low.cmplt(limit).bitmask()) | u64::from(high.cmplt(limit).bitmask()) << 4
}

/// The slots of `values` below `limit`, a bit each from the lowest.
#[inline(always)]
fn slots_below(values: &[f32; PATCH], limit: f32) -> u64 {
    (0..PATCH / 8).fold(0, |bits, r| {
        let four = |first: usize| Vec4::from_slice(&values[first..first + 4]);
        bits | under([four(8 * r), four(8 * r + 4)], limit) << (8 * r)
    })
}

/// The box of each row of 8 slots of `frame`.
fn row_boxes(frame: &Frame) -> [(Vec3, Vec3); PATCH / 8] {
    std::array::from_fn(|r| {
        (8 * r..8 * r + 8)
            .map(|j| point_of(frame, j))
            .fold((Vec3::INFINITY, Vec3::NEG_INFINITY), |(low, high), x| {
                (low.min(x), high.max(x))
            })
    })
}

/// The slots whose bits are set in `bits`, ascending.
fn slots_of(mut bits: u64) -> impl Iterator<Item = usize> {
    std::iter::from_fn(move || {
        (bits != 0).then(|| {
            let k = bits.trailing_zeros() as usize;
            bits &= bits - 1;
            k
        })
    })
}

/// What one step's check needs besides the culling.
struct Check<'a, P: ?Sized> {
    points: &'a P,
    /// The distance plus rounding's margin: a pair at least this far apart is clear.
    clear_at: f32,
    /// `clear_at` plus [`MARGIN`]: a pair at least this far apart leaves its patches cleared.
    suspect_at: f32,
}

impl Culling {
    /// Whether any unjoined pair of `points` can be closer than `distance` (vertices joined
    /// by a spring of `adjacency` do not count), and if so, which vertices. Builds itself on
    /// the first call, and again when the vertex or spring count changes (the points'
    /// places are kept: a culling serves one owner's positions).
    pub fn prove<P: Points + ?Sized>(
        &mut self,
        points: &P,
        adjacency: &Adjacency,
        distance: f32,
    ) -> Proof {
        let proof = self.check(points, adjacency, distance);
        if proof == Proof::Clear {
            self.cleared += 1;
        } else {
            self.uncleared += 1;
        }
        proof
    }

    /// Groups the vertices into patches by where they lie in `layout` (positions in mesh
    /// order; ignored while their count is not the points'), not where the points lie when
    /// the culling is built. Patches should be pieces of the surface: a sheet resumed, or
    /// rebuilt after a tear, in folds grouped by where it lay then put vertices of different
    /// layers in one patch and a patch's vertices in no block of the owner's. (500 steps of
    /// `hooke run --resume` of the bench's 512^2 workload in contact from step 1000 took
    /// 20.2-23.7 ms a step grouped that way, three runs, and 2.2-3.2 grouped by the scene's
    /// layout, with the same bits as one run from the start.)
    pub fn group_by(&mut self, layout: &[Vec3]) {
        self.group_in_order(morton_order(layout));
    }

    /// Groups the vertices into patches as they come in `order` (every vertex once; ignored
    /// while its length is not the points' count), a run of [`PATCH`] each: see
    /// [`Culling::group_by`], and [`super::patch_order`] for a mesh laid out in folds.
    pub fn group_in_order(&mut self, order: Vec<u32>) {
        self.order = order;
        self.built_for = (0, 0);
    }

    /// How long the last proof took to measure the patches; the rest went to their pairs.
    pub fn measuring(&self) -> Duration {
        self.measuring
    }

    /// The vertices of the last [`Proof::Local`]'s suspect patches.
    pub fn suspects(&self) -> &[u32] {
        &self.suspects
    }

    /// Whether `vertex` is one of [`Culling::suspects`].
    pub fn is_suspect(&self, vertex: u32) -> bool {
        let slot = self.slot_of[vertex as usize] as usize;
        self.suspect_bits_of((slot / PATCH) as u32) >> (slot % PATCH) & 1 != 0
    }

    /// Which of patch `p`'s vertices ([`Culling::members_of`]) are suspects, a bit each.
    pub fn suspect_bits_of(&self, p: u32) -> u64 {
        self.suspect_closes[p as usize].bits
    }

    /// The box patch `p`'s suspect vertices lie in (where they were at the last proof, or for
    /// those [`Culling::widen`] added, when added).
    pub fn suspect_box_of(&self, p: u32) -> (Vec3, Vec3) {
        let close = &self.suspect_closes[p as usize];
        (close.low, close.high)
    }

    /// How far, m, beyond the distance every vertex outside [`Culling::suspects`] was from
    /// every unjoined vertex at the last [`Proof::Local`].
    pub fn margin(&self) -> f32 {
        self.margin
    }

    /// The patches with suspect vertices, in the order they gained some (a patch appears
    /// again when it gains more).
    pub fn suspect_patches(&self) -> &[u32] {
        &self.suspect_list
    }

    /// The vertices of patch `p`.
    pub fn members_of(&self, p: u32) -> &[u32] {
        &self.members[self.slots(p)]
    }

    /// Where the positions' owner keeps the vertices of patch `p` ([`Points::place`]).
    pub fn places_of(&self, p: u32) -> &[u32] {
        &self.places[self.slots(p)]
    }

    /// Calls `each` with every patch whose box at the last proof came within `reach` of the
    /// box `low..high` along every axis (boxes no further apart than that on any axis).
    pub fn patches_near(&self, low: Vec3, high: Vec3, reach: f32, mut each: impl FnMut(u32)) {
        self.patches_near_by(low, high, reach, |p, _| each(p));
    }

    /// The patches that may hold a vertex a step's local passes move: every patch whose box
    /// at the last proof came within `reach` of a suspect's box (the suspects' boxes as the
    /// proof left them, before any widening), with the patches near them (see [`Zone`]).
    /// `reach` is how far from those boxes a vertex may lie and still be made suspect by a
    /// chain of widenings before the last pass.
    pub fn zone(&self, reach: f32) -> Zone {
        // The suspects' boxes, merged where they come within `reach` of each other: a walk
        // of the hierarchy per group of them rather than per suspect patch (some 100 at
        // 512^2 in contact). A merged box holds its parts, so it finds every patch they do.
        let mut groups: Vec<(Vec3, Vec3)> = Vec::new();
        for &p in &self.suspect_list {
            let b = self.suspect_box_of(p);
            match groups.iter_mut().find(|g| box_gap(**g, b) < reach) {
                Some(g) => *g = (g.0.min(b.0), g.1.max(b.1)),
                None => groups.push(b),
            }
        }
        let mut seen = vec![false; self.patches.len()];
        let mut moving = Vec::new();
        for &(low, high) in &groups {
            self.patches_near(low, high, reach, |p| {
                if !std::mem::replace(&mut seen[p as usize], true) {
                    moving.push(p);
                }
            });
        }
        Zone {
            groups,
            reach,
            moving,
            places: Arc::clone(&self.places),
            near_offsets: Arc::clone(&self.near_offsets),
            near_patches: Arc::clone(&self.near_patches),
        }
    }

    /// How far from where a vertex that travelled past the margin got to a widening makes
    /// vertices suspect, m (see [`Culling::widen`]).
    pub fn widening_reach(&self) -> f32 {
        self.clear_at + self.margin
    }

    /// [`Culling::patches_near`], each patch with how far its box lies from `low..high`
    /// along the axis that parts them most. A walk with a larger reach meets the patches a
    /// smaller one would, in the same order: a box holds its halves' boxes, so a node the
    /// smaller reach leaves out holds only patches at least as far.
    fn patches_near_by(&self, low: Vec3, high: Vec3, reach: f32, mut each: impl FnMut(u32, f32)) {
        let mut stack = vec![0u32];
        while let Some(node) = stack.pop() {
            let node = self.nodes[node as usize];
            let outside = (node.low - high).max(low - node.high).max_element();
            if outside >= reach {
                continue;
            }
            match node.children {
                Some(children) => stack.extend(children),
                None => each(node.first, outside),
            }
        }
    }

    /// How many patches there are.
    pub fn patch_count(&self) -> usize {
        self.patches.len()
    }

    /// Adds to the suspects every vertex that a vertex at `point` may come within the
    /// distance of before it travels a further margin, for a vertex that has travelled
    /// further than the margin since the last proof (or since it last widened them): those
    /// within the distance and the margin. The vertices that are not suspects yet have not
    /// moved: they are where `points` has them, in their patches' boxes of the last proof.
    ///
    /// Adds to `covers` the patches within `cover_reach` of `point`, as
    /// [`Culling::patches_near`] lists them: what the next covering must add for it (one walk
    /// of the hierarchy for both, where the covering walked it again; 60-110 widenings a
    /// step at 512^2 in contact, a quarter of a microsecond a walk).
    pub fn widen<P: Points + ?Sized>(
        &mut self,
        point: Vec3,
        points: &P,
        cover_reach: f32,
        covers: &mut Vec<u32>,
    ) {
        let reach = self.widening_reach();
        let mut found = Vec::new();
        self.patches_near_by(point, point, reach.max(cover_reach), |p, outside| {
            if outside < reach {
                found.push(p);
            }
            if outside < cover_reach {
                covers.push(p);
            }
        });
        let within = reach * reach;
        for p in found {
            let mut close = self.suspect_closes[p as usize];
            let before = close.bits;
            let frame = self.current(points, p);
            for k in slots_of(slots_within(&frame, self.slots(p).len(), point, within) & !before) {
                close.add(k, point_of(&frame, k));
            }
            if close.bits != before {
                self.suspect_closes[p as usize] = close;
                self.widened += 1;
                self.list_suspects(p, close.bits & !before);
            }
        }
    }

    /// Lists patch `p` and its vertices of `bits`, made suspect.
    fn list_suspects(&mut self, p: u32, bits: u64) {
        self.suspect_list.push(p);
        let members = &self.members[self.slots(p)];
        self.suspects.extend(slots_of(bits).map(|k| members[k]));
    }

    fn check<P: Points + ?Sized>(
        &mut self,
        points: &P,
        adjacency: &Adjacency,
        distance: f32,
    ) -> Proof {
        self.measuring = Duration::ZERO;
        if points.count() == 0 {
            return Proof::Clear;
        }
        let mut watch = Stopwatch::start(self.timing);
        if self.built_for != (points.count(), adjacency.neighbors.len()) {
            self.build(points, adjacency);
        }
        let measured = self.measure_patches(points, distance);
        self.measuring = watch.lap();
        let Some(scale) = measured else {
            return Proof::Nothing;
        };
        // Rounding: a few units in the last place of the largest coordinate in each quantity
        // the bound adds up, and a thousandth of the distance besides.
        let clear_at = distance * 1.001 + scale * 1e-5;
        (self.margin, self.clear_at) = (MARGIN * distance, clear_at);
        let check = Check {
            points,
            clear_at,
            suspect_at: clear_at + self.margin,
        };
        let (contact, suspect_pairs) = self.near_and_far_pairs(&check);
        if !contact {
            return Proof::Clear;
        }
        self.name_suspects(suspect_pairs, &check);
        Proof::Local
    }

    /// Makes suspect every vertex of `pairs` (pairs of patches in which some unjoined pair
    /// is within the distance plus the margin) that is itself within that of an unjoined
    /// vertex of the other patch, and lists them; a pair comes with those vertices if its
    /// check already named them. Vertex by vertex, not the pairs' whole patches: where a
    /// sheet folds through a patch, a row or two of its vertices are that close (a third of
    /// the whole patches' vertices at 512^2 in contact, a fifth at 256^2), and each suspect
    /// costs a window test per pass.
    fn name_suspects<P: Points + ?Sized>(&mut self, pairs: SuspectPairs, check: &Check<P>) {
        let closes: Vec<([u32; 2], [Close; 2])> = pairs
            .into_par_iter()
            .map(|(pair, named)| {
                (
                    pair,
                    named.unwrap_or_else(|| self.close_slots(pair, check).0),
                )
            })
            .collect();
        if self.suspect_closes.len() == self.patches.len() {
            // Only the patches listed since the last naming have suspects (and a box): a patch
            // gains them only here or in a widening, and both list it. (One thread reset all
            // 4,096 of the 512^2 grid's, and scanned them, while the other waited.)
            for &p in &self.suspect_list {
                self.suspect_closes[p as usize] = Close::NONE;
            }
        } else {
            self.suspect_closes.clear();
            self.suspect_closes.resize(self.patches.len(), Close::NONE);
        }
        let mut named = Vec::with_capacity(2 * closes.len());
        for (pair, close) in closes {
            for (p, close) in pair.into_iter().zip(close) {
                if close.bits != 0 {
                    self.suspect_closes[p as usize].join(close);
                    named.push(p);
                }
            }
        }
        // Listed in patch order, each once.
        named.sort_unstable();
        named.dedup();
        self.suspects.clear();
        self.suspect_list.clear();
        for p in named {
            self.list_suspects(p, self.suspect_closes[p as usize].bits);
        }
    }

    /// The vertices of patches `p` and `q` (where `points` has them now) within the distance
    /// plus the margin of an unjoined vertex of the other patch: `[p's, q's]` (alike when
    /// `p == q`); and whether some unjoined pair is within the distance (closer than
    /// `clear_at`). A row of 8 slots is measured only against the other patch's rows whose
    /// boxes come that close to its own.
    fn close_slots<P: Points + ?Sized>(
        &self,
        [p, q]: [u32; 2],
        check: &Check<P>,
    ) -> ([Close; 2], bool) {
        wide(
            #[inline(always)]
            || {
                let others = self.current(check.points, q);
                let mine = if p == q {
                    others
                } else {
                    self.current(check.points, p)
                };
                let (first, count) = (self.slots(p).start, self.slots(p).len());
                let count_q = self.slots(q).len();
                let (rows_p, rows_q) = (row_boxes(&mine), row_boxes(&others));
                let within = check.suspect_at * check.suspect_at;
                let touching = check.clear_at * check.clear_at;
                let (mut close_p, mut close_q) = (Close::NONE, Close::NONE);
                let mut contact = false;
                for (r, &(low, high)) in rows_p.iter().enumerate().take(count.div_ceil(8)) {
                    // `q`'s rows whose boxes come that close to this one's, a bit each.
                    let near_rows = (0..count_q.div_ceil(8)).fold(0u64, |rows, s| {
                        let (other_low, other_high) = rows_q[s];
                        let gap = (other_low - high).max(low - other_high).max(Vec3::ZERO);
                        rows | u64::from(gap.length_squared() < within) << s
                    });
                    if near_rows == 0 {
                        continue;
                    }
                    for k in 8 * r..(8 * r + 8).min(count) {
                        let x = point_of(&mine, k);
                        let (mut near, mut touch) = (0u64, 0u64);
                        for s in slots_of(near_rows) {
                            let squared = row_squared(&others, s, x);
                            near |= under(squared, within) << (8 * s);
                            touch |= under(squared, touching) << (8 * s);
                        }
                        near &= u64::MAX >> (PATCH - count_q);
                        if p == q {
                            near &= !(1 << k);
                        }
                        if near == 0 {
                            continue;
                        }
                        near &= !self.joined_in(first + k, q);
                        if near != 0 {
                            close_p.add(k, x);
                            close_q.bits |= near;
                            // `touching` is below `within`: its slots are among `near`'s.
                            contact |= touch & near != 0;
                        }
                    }
                }
                for j in slots_of(close_q.bits) {
                    close_q.add(j, point_of(&others, j));
                }
                if p == q {
                    close_p.join(close_q);
                    close_q = close_p;
                }
                ([close_p, close_q], contact)
            },
        )
    }

    /// Patches, their near pairs and the hierarchy, for `points` as they are now.
    fn build<P: Points + ?Sized>(&mut self, points: &P, adjacency: &Adjacency) {
        let n = points.count();
        self.members = if self.order.len() == n {
            self.order.clone()
        } else {
            let mut positions = Vec::new();
            points.copy_into(&mut positions);
            morton_order(&positions)
        };
        // Which vertices make a patch is all that matters; by place, a grid's patch is rows of
        // consecutive places, which the owner may lend a run at a time (`Points::run`).
        self.members
            .par_chunks_mut(PATCH)
            .for_each(|members| members.sort_unstable_by_key(|&v| points.place(v)));
        let morton_order = self.number_by_place(points);
        self.slot_of = slots_in(&self.members);
        let slot_of = &self.slot_of;
        self.joined_offsets = std::iter::once(0)
            .chain(self.members.iter().scan(0, |end, &v| {
                *end += adjacency.valence(v as usize);
                Some(*end)
            }))
            .collect();
        self.joined = self
            .members
            .iter()
            .flat_map(|&v| adjacency.neighbors_of(v))
            .map(|&w| slot_of[w as usize])
            .collect();
        self.places = self.members.iter().map(|&v| points.place(v)).collect();
        self.references = self
            .places
            .chunks(PATCH)
            .map(|places| gather(points, places))
            .collect();
        self.block_starts = self
            .places
            .chunks(PATCH)
            .map(|places| {
                let blocked = places.len() == PATCH
                    && places.chunks(LANES).all(|run| points.run(run).is_some());
                blocked.then(|| std::array::from_fn(|row| places[row * LANES]))
            })
            .collect();
        let count = n.div_ceil(PATCH);
        self.standings = vec![Standing::default(); count];
        self.boxes = vec![(Vec3::ZERO, Vec3::ZERO); count];
        self.patches = self
            .references
            .iter()
            .map(|references| {
                // References that are not finite are renewed at the first measurement, which
                // takes their box then.
                let (reference_scale, (reference_low, reference_high)) = scale_and_box(references);
                Patch {
                    centre: Vec3::ZERO,
                    spread: 0.0,
                    shift: DVec3::ZERO,
                    renewed: 0.0,
                    closest: f32::INFINITY,
                    earlier_closest: f32::INFINITY,
                    reference_scale,
                    reference_low,
                    reference_high,
                    low: Vec3::ZERO,
                    high: Vec3::ZERO,
                }
            })
            .collect();
        // Near: patches holding a vertex within two springs of one of the patch's.
        let rows: Vec<Vec<u32>> = (0..count)
            .into_par_iter()
            .map(|p| {
                let mut row = Vec::new();
                for &v in self.members_of(p as u32) {
                    for &w in adjacency.neighbors_of(v) {
                        row.push(slot_of[w as usize] / PATCH as u32);
                        for &u in adjacency.neighbors_of(w) {
                            row.push(slot_of[u as usize] / PATCH as u32);
                        }
                    }
                }
                row.push(p as u32);
                row.sort_unstable();
                row.dedup();
                row
            })
            .collect();
        self.near_offsets = std::iter::once(0)
            .chain(rows.iter().scan(0, |end, row| {
                *end += row.len() as u32;
                Some(*end)
            }))
            .collect();
        self.near = rows
            .iter()
            .enumerate()
            .flat_map(|(p, row)| {
                row.iter()
                    .filter(move |&&q| q >= p as u32)
                    .map(move |&q| NearPair::unmeasured([p as u32, q]))
            })
            .collect();
        self.near_patches = rows.into_iter().flatten().collect();
        self.joined_pairs = self.near.len();
        self.adopted = vec![Vec::new(); count];
        self.nodes.clear();
        self.leaf_of = vec![0; count];
        self.add_node(0, count as u32, &morton_order);
        (self.frontier, self.walked) = (Vec::new(), None);
        self.built_for = (n, adjacency.neighbors.len());
    }

    /// Renumbers the full patches in the order of their first places (a short last patch
    /// stays last); returns the new numbers in the patches' Morton order, which the hierarchy
    /// keeps. (Halving the place order instead gives it strips of patches at its lower levels;
    /// in eight runs each the bench's parts that search it read 4-17% higher by their medians,
    /// within this VM's noise, so the hierarchy keeps the order it was tuned with.)
    ///
    /// Measuring every patch each step reads its points from the owner's memory, a run of 8
    /// places (32 bytes an axis) from each of 8 rows of a grid's mesh. In Morton order of the
    /// patches those runs came in no order a prefetcher could follow, and `perf` put most of
    /// measuring's samples on the instructions waiting for them; in place order a row of
    /// patches reads 24 runs that advance together through the owner's arrays. On an AMD EPYC
    /// VM, measuring's share of the samples of a 1-thread run of the bench's 512^2 workload
    /// in contact was 11.4-17.1% (median 15.1) in Morton order and 10.9-12.9% (11.4) in place
    /// order, nine runs each, with the same moves.
    fn number_by_place<P: Points + ?Sized>(&mut self, points: &P) -> Vec<u32> {
        let whole = self.members.len() / PATCH * PATCH;
        let mut firsts: Vec<(u32, usize)> = self.members[..whole]
            .chunks(PATCH)
            .enumerate()
            .map(|(k, members)| (points.place(members[0]), k))
            .collect();
        firsts.sort_unstable();
        let members = &self.members;
        self.members = firsts
            .iter()
            .flat_map(|&(_, k)| &members[k * PATCH..(k + 1) * PATCH])
            .chain(&members[whole..])
            .copied()
            .collect();
        let mut morton_order: Vec<u32> = (0..self.members.len().div_ceil(PATCH) as u32).collect();
        for (patch, &(_, k)) in firsts.iter().enumerate() {
            morton_order[k] = patch as u32;
        }
        morton_order
    }

    /// Adds the subtree over patches `morton_order[first..end]`; returns its root's index.
    fn add_node(&mut self, first: u32, end: u32, morton_order: &[u32]) -> u32 {
        let index = self.nodes.len() as u32;
        let (node_first, node_end) = if end - first > 1 {
            (first, end)
        } else {
            let patch = morton_order[first as usize];
            self.leaf_of[patch as usize] = index;
            (patch, patch + 1)
        };
        self.nodes.push(Node {
            first: node_first,
            end: node_end,
            children: None,
            low: Vec3::ZERO,
            high: Vec3::ZERO,
        });
        if end - first > 1 {
            let middle = first + (end - first) / 2;
            let children = [
                self.add_node(first, middle, morton_order),
                self.add_node(middle, end, morton_order),
            ];
            self.nodes[index as usize].children = Some(children);
        }
        index
    }

    /// Each patch's centre, spread and box this step, renewing the references of patches
    /// that spread past their slack; then the hierarchy's boxes. Returns the largest
    /// coordinate seen, or `None` if a position is not finite.
    fn measure_patches<P: Points + ?Sized>(&mut self, points: &P, distance: f32) -> Option<f32> {
        let scale = self
            .patches
            .par_iter_mut()
            .zip(self.references.par_iter_mut())
            .zip(self.places.par_chunks(PATCH))
            .zip(self.block_starts.par_iter())
            .zip(self.standings.par_iter_mut().zip(self.boxes.par_iter_mut()))
            .map_init(
                Scratch::new,
                |scratch, ((((patch, references), places), starts), (standing, bounds))| {
                    let rows = match starts.and_then(|starts| blocks_of(points, &starts)) {
                        Some(rows) => rows,
                        None => {
                            gather_into(points, places, &mut scratch.positions);
                            rows_of(&scratch.positions)
                        }
                    };
                    let scale = measure_patch(patch, references, &rows, distance);
                    *standing = Standing::of(patch);
                    *bounds = (patch.low, patch.high);
                    scale
                },
            )
            .try_reduce(|| 0.0, |a, b| Some(a.max(b)))?;
        refit(&mut self.nodes, 0, &self.boxes);
        Some(scale)
    }

    /// Checks every near pair (all of them, so each keeps its cache up to date) and searches
    /// the far pairs. Returns whether any pair is within the distance, and the suspect pairs.
    ///
    /// The two run side by side: both only read the patches, and the far search's top levels
    /// run on one thread (a node's pairs across its halves are searched after both halves),
    /// which the near pairs fill the other threads around. (In contact at 512^2 on 2 threads,
    /// the two took 1-4% less time together this way than one after the other, measured
    /// on alternate steps of the same runs.)
    ///
    /// The near pairs go in two passes: the cached gaps, which clear nearly all of them, then
    /// the few they do not, measured again. Those lie together in the list (where the sheet
    /// folds), so in one pass over it a thread could be left with most of the measuring while
    /// the other ran out of pairs; a second pass over them alone shares it out. (On alternate
    /// steps of the same runs in contact, with the cached gaps of [`Standing`]: 8-10% less
    /// time for the near and far pairs together at 512^2, 16-19% at 256^2.)
    ///
    /// A pair of patches that no springs join is left to the far search until their boxes
    /// come within the distance plus the margin: it is then measured as a near pair and
    /// adopted, its gap cached from then on, until the boxes part again. On a flat sheet, an
    /// irregular mesh's patches (runs of its Morton order) reach past the patches springs
    /// join: the bench's mesh of 65,536 vertices, draped and in no contact, measured some
    /// 1,500 such pairs a step afresh.
    fn near_and_far_pairs<P: Points + ?Sized>(&mut self, check: &Check<P>) -> (bool, SuspectPairs) {
        self.proofs += 1;
        if self.proofs.is_multiple_of(PARTING_EVERY) {
            self.give_back_parted(check.suspect_at * PARTED);
        }
        let mut near = std::mem::take(&mut self.near);
        let mut frontier = std::mem::take(&mut self.frontier);
        let walk = self
            .walked
            .is_none_or(|walked| frontier.len() > REWALK_GROWTH * walked.max(self.patches.len()));
        let this = &*self;
        let (mut news, far) = rayon::join(
            || {
                let due: Vec<usize> = near
                    .par_iter_mut()
                    .enumerate()
                    .filter_map(|(i, pair)| {
                        if !this.cached_clear(pair, check) {
                            return Some(i);
                        }
                        // Written only when it changes: most pairs' lines then stay clean.
                        if pair.suspect {
                            pair.suspect = false;
                        }
                        None
                    })
                    .collect();
                let near = &near;
                // The due pairs lie at random in the patches' memory: each task asks for the
                // next pair's lines while it measures one.
                due.par_chunks(DUE_TASK)
                    .flat_map_iter(|task| {
                        task.iter().enumerate().map(move |(t, &i)| {
                            if let Some(&next) = task.get(t + 1) {
                                this.prefetch_pair(&near[next], check.points);
                            }
                            (i, this.measure_near_pair(&near[i], check))
                        })
                    })
                    .collect::<Vec<_>>()
            },
            || this.far_pairs(&mut frontier, walk, check),
        );
        if walk {
            self.walks += 1;
            self.walked = Some(frontier.len());
        }
        self.frontier = frontier;
        for (patches, measured) in far {
            news.push((near.len(), measured));
            near.push(NearPair::unmeasured(patches));
            self.adopted[patches[0] as usize].push(patches[1]);
        }
        let (mut contact, mut suspects) = (false, Vec::new());
        for (i, (found, measured, named)) in news {
            let pair = &mut near[i];
            pair.suspect = found.suspect;
            if let Some(gap) = measured {
                // From the standings `cached_clear` compares them with.
                let [p, q] = pair.patches.map(|patch| patch as usize);
                let offset = self.standings[p].moved - self.standings[q].moved;
                pair.measured(gap, offset, [p, q].map(|p| self.patches[p].renewed));
            }
            contact |= found.contact;
            if found.suspect {
                suspects.push((pair.patches, named));
            }
            if let Some(gap) = measured {
                for patch in pair.patches {
                    let patch = &mut self.patches[patch as usize];
                    patch.closest = patch.closest.min(gap);
                }
            }
        }
        self.near = near;
        (contact, suspects)
    }

    /// Gives the adopted pairs whose boxes are now `apart` or more apart back to the far
    /// search.
    fn give_back_parted(&mut self, apart: f32) {
        let patches = &self.patches;
        let adopted = &mut self.adopted;
        let mut k = self.joined_pairs;
        while k < self.near.len() {
            let [p, q] = self.near[k].patches;
            let (a, b) = (&patches[p as usize], &patches[q as usize]);
            if box_gap((a.low, a.high), (b.low, b.high)) >= apart {
                let row = &mut adopted[p as usize];
                if let Some(at) = row.iter().position(|&r| r == q) {
                    row.swap_remove(at);
                }
                self.near.swap_remove(k);
                let leaves = [self.leaf_of[p as usize], self.leaf_of[q as usize]];
                self.frontier.push(leaves);
            } else {
                k += 1;
            }
        }
    }

    /// Asks for the lines [`Culling::measure_near_pair`] reads first: the patches, the
    /// offsets of `p`'s joined slots, and the patches' references or, where it names a
    /// suspect pair's vertices, their places and points (those that fill the owner's blocks).
    /// (Asked for one pair ahead, 512^2 in contact: the near and far pairs about 3% shorter
    /// by median, on alternate steps of the same runs; two pairs ahead, no shorter.)
    fn prefetch_pair<P: Points + ?Sized>(&self, pair: &NearPair, points: &P) {
        // `p`'s joined slots, which the search asks for as it starts.
        let slots = self.slots(pair.patches[0]);
        prefetch_lines(&self.joined_offsets[slots.start..=slots.end]);
        for patch in pair.patches {
            let patch = patch as usize;
            prefetch(&self.patches[patch]);
            if !pair.suspect {
                self.references[patch]
                    .iter()
                    .for_each(|axis| prefetch_lines(axis));
            } else {
                prefetch_lines(&self.places[self.slots(patch as u32)]);
                for start in self.block_starts[patch].into_iter().flatten() {
                    for axis in points.lanes(start).into_iter().flatten() {
                        prefetch(axis);
                    }
                }
            }
        }
    }

    /// Whether a near pair's cached gap, less what renewals since (their spreads) and the
    /// patches' drift towards each other may have taken off it, still clears it.
    fn cached_clear<P: ?Sized>(&self, pair: &NearPair, check: &Check<P>) -> bool {
        let [p, q] = pair.patches;
        let (a, b) = (&self.standings[p as usize], &self.standings[q as usize]);
        let left = pair.budget - (a.taken + b.taken) - f64::from(check.suspect_at);
        // What the drift may take, compared squared: no square root a pair.
        left >= 0.0 && (a.moved - b.moved - pair.offset.as_dvec3()).length_squared() <= left * left
    }

    /// What a near pair that its cached gap does not clear shows, its gap if it had to be
    /// measured again, and its suspect vertices if they were named.
    fn measure_near_pair<P: Points + ?Sized>(&self, pair: &NearPair, check: &Check<P>) -> Measured {
        let [p, q] = pair.patches;
        let (a, b) = (&self.patches[p as usize], &self.patches[q as usize]);
        let current = |patch: u32| self.current(check.points, patch);
        if pair.suspect {
            // In contact last step: the placed gap would most likely fail again, and the
            // pair most likely has suspects. They are named here, which also shows whether
            // it is in contact: measuring the pair first, then naming its suspects, read and
            // measured the same points twice. (A step with no contact anywhere names none, so
            // there the naming is spent for nothing; in contact last step makes that rare.)
            let (closes, contact) = self.close_slots([p, q], check);
            let suspect = closes[0].bits != 0;
            let found = Found { suspect, contact };
            return (found, None, suspect.then_some(closes));
        }
        let placed = |patch: u32| {
            let mut frame = self.references[patch as usize];
            let centre = self.patches[patch as usize].centre.to_array();
            for (axis, c) in frame.iter_mut().zip(centre) {
                axis.iter_mut().for_each(|x| *x += c);
            }
            frame
        };
        let gap = self.closest_unjoined([p, q], placed, 0.0);
        if gap - a.spread - b.spread >= check.suspect_at {
            return (Found::default(), Some(gap), None);
        }
        // Both on their references (just renewed, say): the gap is the current distance.
        let still = |patch: &Patch| patch.spread == 0.0 && patch.centre == Vec3::ZERO;
        if still(a) && still(b) {
            return (Found::at(gap, check), Some(gap), None);
        }
        let closest = self.closest_unjoined([p, q], current, check.clear_at);
        (Found::at(closest, check), Some(gap), None)
    }

    /// The pairs of patches that are not near but whose boxes are within the distance plus the
    /// margin, each measured as a near pair (see [`Culling::measure_near_pair`]).
    ///
    /// A walk down the hierarchy from its root to them, each step, went down to every pair of
    /// patches whose boxes touch (a sheet's neighbours), only to find them near: on the 512^2
    /// grid's sheet in contact some 17,000 pairs of nodes were left as too far apart and
    /// 7,000 pairs of patches reached, a step. The search keeps the pairs of nodes where a walk
    /// stopped instead (`frontier`: those too far apart, and pairs of patches that are not
    /// near), less the pairs of patches it found since, which are adopted. Each step it checks
    /// them alone, walks on from those that have come within reach, and keeps where that walk
    /// stopped. A pair given back is added to them again. Those too far apart are nodes that
    /// moved towards each other since, so their number only grows; past [`REWALK_GROWTH`]
    /// times the patches (or what the last walk left) the hierarchy is walked again from its
    /// root (`walk`).
    fn far_pairs<P: Points + ?Sized>(
        &self,
        frontier: &mut Vec<[u32; 2]>,
        walk: bool,
        check: &Check<P>,
    ) -> Vec<([u32; 2], Measured)> {
        let reach = check.suspect_at;
        let mut close = Vec::new();
        if walk {
            frontier.clear();
            self.search_within(0, reach, frontier, &mut close);
        } else {
            let mut further = Vec::new();
            frontier.retain(|&[a, b]| {
                let within = self.nodes[a as usize].gap(&self.nodes[b as usize]) < reach;
                if within {
                    self.search_between(a, b, reach, &mut further, &mut close);
                }
                !within
            });
            frontier.append(&mut further);
        }
        close
            .into_par_iter()
            .map(|pair| {
                (
                    pair,
                    self.measure_near_pair(&NearPair::unmeasured(pair), check),
                )
            })
            .collect()
    }

    /// Walks the pairs of patches under `node`: see [`Culling::search_between`].
    fn search_within(
        &self,
        node: u32,
        reach: f32,
        stops: &mut Vec<[u32; 2]>,
        close: &mut Vec<[u32; 2]>,
    ) {
        let node = &self.nodes[node as usize];
        let Some([a, b]) = node.children else {
            return;
        };
        if node.end - node.first >= PARALLEL_PATCHES {
            let (mut stops_b, mut close_b) = (Vec::new(), Vec::new());
            rayon::join(
                || self.search_within(a, reach, stops, close),
                || self.search_within(b, reach, &mut stops_b, &mut close_b),
            );
            stops.append(&mut stops_b);
            close.append(&mut close_b);
        } else {
            self.search_within(a, reach, stops, close);
            self.search_within(b, reach, stops, close);
        }
        self.search_between(a, b, reach, stops, close);
    }

    /// Walks the pairs of a patch under node `a` and one under node `b` that are not near:
    /// adds to `close` those whose boxes are within `reach` of each other, and to `stops` the
    /// pairs of nodes (or of patches) where it stopped, their boxes further apart.
    fn search_between(
        &self,
        a: u32,
        b: u32,
        reach: f32,
        stops: &mut Vec<[u32; 2]>,
        close: &mut Vec<[u32; 2]>,
    ) {
        let (na, nb) = (&self.nodes[a as usize], &self.nodes[b as usize]);
        // Measured only where it decides: most pairs of patches a walk reaches are near.
        let apart = || na.gap(nb) >= reach;
        // Split the larger node (a single patch cannot be).
        let ([first, second], split_a) = match (na.children, nb.children) {
            (None, None) => {
                let (p, q) = (na.first.min(nb.first), na.first.max(nb.first));
                if !self.near(p, q) {
                    if apart() {
                        stops.push([a, b]);
                    } else {
                        close.push([p, q]);
                    }
                }
                return;
            }
            _ if apart() => {
                stops.push([a, b]);
                return;
            }
            (Some(halves), None) => (halves, true),
            (None, Some(halves)) => (halves, false),
            (Some(halves_a), Some(halves_b)) => {
                if na.end - na.first >= nb.end - nb.first {
                    (halves_a, true)
                } else {
                    (halves_b, false)
                }
            }
        };
        if split_a {
            self.search_between(first, b, reach, stops, close);
            self.search_between(second, b, reach, stops, close);
        } else {
            self.search_between(a, first, reach, stops, close);
            self.search_between(a, second, reach, stops, close);
        }
    }

    /// Whether `p` and `q` (`p < q`) are a near pair, joined or adopted.
    fn near(&self, p: u32, q: u32) -> bool {
        let row =
            self.near_offsets[p as usize] as usize..self.near_offsets[p as usize + 1] as usize;
        self.near_patches[row].binary_search(&q).is_ok() || self.adopted[p as usize].contains(&q)
    }

    /// Patch `p`'s points where `points` has them now.
    fn current<P: Points + ?Sized>(&self, points: &P, p: u32) -> Frame {
        gather(points, &self.places[self.slots(p)])
    }

    /// The slots of `members` joined to slot `slot`'s vertex by a spring.
    fn joined_of(&self, slot: usize) -> &[u32] {
        &self.joined[self.joined_offsets[slot] as usize..self.joined_offsets[slot + 1] as usize]
    }

    /// The slots of patch `q` joined to slot `slot`'s vertex by a spring, a bit each.
    #[inline(always)]
    fn joined_in(&self, slot: usize, q: u32) -> u64 {
        self.joined_of(slot)
            .iter()
            .filter(|&&joined| joined as usize / PATCH == q as usize)
            .fold(0, |bits, &joined| bits | 1 << (joined as usize % PATCH))
    }

    /// Slots of patch `p` in `members`.
    fn slots(&self, p: u32) -> std::ops::Range<usize> {
        let first = p as usize * PATCH;
        first..(first + PATCH).min(self.members.len())
    }

    /// The smallest distance between a vertex of patch `p` and one of patch `q` that no spring
    /// joins (not a vertex and itself), with each patch's vertices at `frame(patch)`; or, as
    /// soon as a pair closer than `enough` turns up, that pair's distance (a caller that only
    /// asks whether some pair is that close needs no more).
    ///
    /// `p`'s vertex nearest `q`'s box is taken first, then only those whose distance to the box
    /// is less than the closest pair found so far: no other can be closer. Patches side by
    /// side on a sheet then measure a row or two of `p`, not all 64.
    fn closest_unjoined(&self, [p, q]: [u32; 2], frame: impl Fn(u32) -> Frame, enough: f32) -> f32 {
        // Compiled for AVX2 where there is one: the rows below are 64 lanes wide.
        wide(
            #[inline(always)]
            || {
                // `p`'s joined slots are read a row at a time in no order the processor can
                // foresee: they are asked for first, to arrive while the frames are built.
                let slots = self.slots(p);
                let first = slots.start;
                let offsets = &self.joined_offsets[first..=slots.end];
                let joined = offsets[0] as usize..offsets[offsets.len() - 1] as usize;
                prefetch_lines(offsets);
                prefetch_lines(&self.joined[joined]);
                // `q`'s points by axis, unused slots far away, so each row below is a plain
                // loop (a frame's unused slots repeat its first point: its box is the same).
                let mut others = frame(q);
                let (low, high) = corners(&others);
                let mine = if p == q { others } else { frame(p) };
                for axis in &mut others {
                    axis[self.slots(q).len()..].fill(f32::INFINITY);
                }
                // Each of `p`'s points' squared distance to the box, a slot past its members
                // infinite, in a loop over whole axes the compiler vectorises.
                let mut to_box = [0.0f32; PATCH];
                for (k, d) in to_box.iter_mut().enumerate() {
                    let outside = |a: usize, low: f32, high: f32| {
                        let x = mine[a][k];
                        larger(larger(low - x, x - high), 0.0)
                    };
                    let (ox, oy, oz) = (
                        outside(0, low.x, high.x),
                        outside(1, low.y, high.y),
                        outside(2, low.z, high.z),
                    );
                    *d = ox * ox + oy * oy + oz * oz;
                }
                to_box[slots.len()..].fill(f32::INFINITY);
                // The point nearest the box first, which makes `closest` small at once; then
                // every other point in slot order that could still come closer than it. (A
                // full sort by distance, taken before, took a quarter of this search's time.)
                // The least distance in vector registers, then the first slot that has it: a
                // fold that carried the slot along ran one comparison at a time, a fifth of
                // this search's own `perf` samples.
                let least = to_box.iter().fold(f32::INFINITY, |a, &b| smaller(a, b));
                let nearest = to_box.iter().position(|&d| d == least).unwrap_or(0);
                let enough = enough * enough;
                let mut closest = f32::INFINITY;
                // The others as a bit each, listed once the nearest has set `closest`: a test
                // a slot in slot order, whose outcome follows no pattern, ran 3-11% longer a
                // search of two patches (the same searches timed both ways).
                let (mut candidates, mut listed) = (1u64 << nearest, false);
                while candidates != 0 && closest >= enough {
                    let k = candidates.trailing_zeros() as usize;
                    candidates &= candidates - 1;
                    if to_box[k] >= closest {
                        continue;
                    }
                    // The slots of `q` that the vertex is itself or joined to, a bit each.
                    let itself = if p == q { 1u64 << k } else { 0 };
                    let joined = itself | self.joined_in(first + k, q);
                    // A patch paired with itself would meet each pair of its slots twice,
                    // from either end: a slot is measured against the rows of 8 from its own
                    // on, which still meets each pair `i < j` from `i`.
                    let from = if p == q { k / 8 } else { 0 };
                    // The smallest over 8 lanes, each folding every 8th slot: 8 slots at a
                    // time in one vector register, where a fold over all 64 in order ran a
                    // slot at a time.
                    let x = point_of(&mine, k);
                    let mut lanes = [f32::INFINITY; 8];
                    for c in from..PATCH / 8 {
                        let bits = (joined >> (8 * c)) as u32;
                        for (l, lane) in lanes.iter_mut().enumerate() {
                            let j = 8 * c + l;
                            let d = [others[0][j] - x.x, others[1][j] - x.y, others[2][j] - x.z];
                            let squared = d[0] * d[0] + d[1] * d[1] + d[2] * d[2];
                            let masked = (bits >> l) & 1 != 0;
                            *lane = smaller(*lane, if masked { f32::INFINITY } else { squared });
                        }
                    }
                    closest = lanes.iter().fold(closest, |a, &b| smaller(a, b));
                    if !listed {
                        listed = true;
                        candidates = slots_below(&to_box, closest) & !(1u64 << nearest);
                    }
                }
                closest.sqrt()
            },
        )
    }
}

/// A patch's points as 8 rows of [`LANES`] slots, by axis: slots `8 r..8 r + 8` of a frame,
/// or one of the owner's blocks.
type Rows<'a> = [[&'a [f32; LANES]; 3]; PATCH / LANES];

/// The rows of a patch whose members fill 8 blocks of the owner, straight from them: the
/// blocks at `starts`.
fn blocks_of<'a, P: Points + ?Sized>(
    points: &'a P,
    starts: &[u32; PATCH / LANES],
) -> Option<Rows<'a>> {
    const NONE: [f32; LANES] = [0.0; LANES];
    let mut rows = [[&NONE; 3]; PATCH / LANES];
    for (row, &start) in rows.iter_mut().zip(starts) {
        *row = points.lanes(start)?;
    }
    Some(rows)
}

/// The rows of a frame.
fn rows_of(frame: &Frame) -> Rows<'_> {
    let axes = frame.each_ref().map(|axis| axis.as_chunks::<LANES>().0);
    std::array::from_fn(|r| axes.map(|axis| &axis[r]))
}

/// One patch's step: see [`Culling::measure_patches`]. Returns its largest coordinate, or
/// `None` if a position is not finite.
fn measure_patch(
    patch: &mut Patch,
    references: &mut Frame,
    rows: &Rows,
    distance: f32,
) -> Option<f32> {
    // Compiled for AVX2 where there is one: each row's lanes are one vector.
    wide(
        #[inline(always)]
        || measure_patch_with(patch, references, rows, distance),
    )
}

#[inline(always)]
fn measure_patch_with(
    patch: &mut Patch,
    references: &mut Frame,
    rows: &Rows,
    distance: f32,
) -> Option<f32> {
    // The centre of the displacements' box, whose spread is at most half the box's diagonal:
    // a sheet that moves as one has next to none. (A second centre, where the patch's last
    // step of motion carried it, was measured beside it and kept where its spread was
    // smaller: in 37% of the measurements of the 512^2 workload resumed in contact for 500
    // steps, yet without it only 1.2% more pairs of patches were measured (218,184 against
    // 215,499), for 12 vector operations a row here instead of 17.)
    let reference_rows = references
        .each_ref()
        .map(|axis| axis.as_chunks::<LANES>().0);
    // The points' own box is not taken: the references' box moved by the displacements' box
    // holds them. With the finiteness read from a running sum (below; of the squares then),
    // measuring ran a third fewer instructions (callgrind, `hooke run
    // scenes/self-collision.toml --steps 300`: 12.3 million against 18.2).
    let lanes = |value: f32| [value; LANES];
    let (mut moved_low, mut moved_high) =
        ([lanes(f32::INFINITY); 3], [lanes(f32::NEG_INFINITY); 3]);
    // A sum of the displacements keeps a NaN or an infinity (a sum per lane, which the
    // compiler keeps in a vector; the box's minima and maxima may drop a NaN): with finite
    // references, the points are finite unless it is not (or the sum overflows, some 1e37 m:
    // the proof then fails as for a point that is not finite, and the full passes run).
    let mut poison = lanes(0.0);
    for (r, row) in rows.iter().enumerate() {
        for a in 0..3 {
            let (x, reference) = (row[a], &reference_rows[a][r]);
            for l in 0..LANES {
                let d = x[l] - reference[l];
                moved_low[a][l] = smaller(moved_low[a][l], d);
                moved_high[a][l] = larger(moved_high[a][l], d);
                poison[l] += d;
            }
        }
    }
    if patch.reference_scale.is_finite() && poison.iter().any(|p| !p.is_finite()) {
        return None;
    }
    // Across the lanes, a half of the row against the other, then glam's reductions of 4.
    let halves =
        |lanes: &[f32; LANES]| (Vec4::from_slice(&lanes[..4]), Vec4::from_slice(&lanes[4..]));
    let least = |axes: [[f32; LANES]; 3]| {
        Vec3::from_array(axes.map(|axis| {
            let (a, b) = halves(&axis);
            a.min(b).min_element()
        }))
    };
    let most = |axes: [[f32; LANES]; 3]| {
        Vec3::from_array(axes.map(|axis| {
            let (a, b) = halves(&axis);
            a.max(b).max_element()
        }))
    };
    let (moved_low, moved_high) = (least(moved_low), most(moved_high));
    let (centre, spread) = (
        0.5 * (moved_low + moved_high),
        0.5 * (moved_high - moved_low).length(),
    );
    // An eighth of the slack its near pairs had when measured (and a fortieth of the distance
    // while none is measured or one is in contact), so a patch renews only when it has bent
    // or turned enough to matter. References that are not finite (say, taken from a state
    // that was not) are renewed. A renewal takes its spread off every cached gap of the
    // patch, but so does a spread left standing: the 512^2 workload resumed in contact for
    // 500 steps measured 215,499 pairs of patches with these shares (113,217 renewals)
    // against 250,396 with a quarter and a tenth (65,355 renewals), with the same moves.
    let closest = if patch.closest.is_finite() {
        patch.closest
    } else {
        patch.earlier_closest
    };
    let renew_above = (0.125 * (closest - distance)).max(0.025 * distance);
    if patch.reference_scale.is_finite() && spread <= renew_above {
        (patch.centre, patch.spread) = (centre, spread);
        // Each point is its reference plus its displacement, but for the rounding of the
        // displacement and of these sums: half a unit in the last place each, of the largest
        // coordinate at most; eight are allowed.
        let (low, high) = (
            patch.reference_low + moved_low,
            patch.reference_high + moved_high,
        );
        let rounding = low.abs().max(high.abs()).max_element() * 1e-6;
        (patch.low, patch.high) = (low - rounding, high + rounding);
    } else {
        // The new references are the old ones moved by `centre` and by at most `spread`
        // besides, so each cached gap, kept in the old frame, holds less `spread` (and the
        // rounding of both, a few units in their last place, which the chain of renewals
        // between two measurements adds up).
        for (axis, references) in references.iter_mut().enumerate() {
            for (row, slots) in rows.iter().zip(references.as_chunks_mut::<LANES>().0) {
                *slots = *row[axis];
            }
        }
        // Old references that were not finite told nothing of the points: they are now.
        let reference_box;
        (patch.reference_scale, reference_box) = scale_and_box(references);
        if !patch.reference_scale.is_finite() {
            return None;
        }
        (patch.reference_low, patch.reference_high) = reference_box;
        (patch.low, patch.high) = (patch.reference_low, patch.reference_high);
        patch.shift += centre.as_dvec3();
        patch.renewed += f64::from(spread) * (1.0 + 1e-5) + f64::from(centre.length()) * 1e-6;
        (patch.centre, patch.spread) = (Vec3::ZERO, 0.0);
        patch.earlier_closest = closest;
        patch.closest = f32::INFINITY;
    }
    let scale = patch.low.abs().max(patch.high.abs()).max_element();
    Some(scale.max(patch.reference_scale))
}

/// How far apart two boxes are along the axis that parts them most (negative where they
/// overlap on every axis): no point of one is closer than that to a point of the other.
fn box_gap((low_a, high_a): (Vec3, Vec3), (low_b, high_b): (Vec3, Vec3)) -> f32 {
    (low_a - high_b).max(low_b - high_a).max_element()
}

/// Each vertex's index in `order` (every vertex once).
pub(super) fn slots_in(order: &[u32]) -> Vec<u32> {
    let mut slots = vec![0u32; order.len()];
    for (slot, &v) in order.iter().enumerate() {
        slots[v as usize] = slot as u32;
    }
    slots
}

/// Whether every value of `frame` is finite.
fn finite(frame: &Frame) -> bool {
    frame.iter().all(|axis| poison(axis) == 0.0)
}

/// The smallest and largest corners of a finite frame's box.
fn corners(frame: &Frame) -> (Vec3, Vec3) {
    let axes = frame.map(|axis| extremes(&axis));
    let corner = |k: usize| Vec3::from_array(axes.map(|e| e[k]));
    (corner(0), corner(1))
}

/// A frame's largest coordinate, m, and its box; infinity and an empty box at the origin if
/// a coordinate is not finite.
fn scale_and_box(frame: &Frame) -> (f32, (Vec3, Vec3)) {
    if !finite(frame) {
        return (f32::INFINITY, (Vec3::ZERO, Vec3::ZERO));
    }
    let (low, high) = corners(frame);
    (low.abs().max(high.abs()).max_element(), (low, high))
}

/// The points at `places` (a patch's; at most `PATCH`), the rest of the frame repeating the
/// first.
fn gather<P: Points + ?Sized>(points: &P, places: &[u32]) -> Frame {
    let mut frame = [[0.0; PATCH]; 3];
    gather_into(points, places, &mut frame);
    frame
}

/// [`gather`] into a frame that exists.
fn gather_into<P: Points + ?Sized>(points: &P, places: &[u32], frame: &mut Frame) {
    let [x, y, z] = frame;
    points.gather_into(places, [x, y, z]);
    for axis in frame {
        let first = axis[0];
        axis[places.len()..].fill(first);
    }
}

/// The frame a task gathers patches into where they do not fill blocks of the owner, kept
/// from one patch to the next: a frame made for each patch is zeroed first, 768 bytes of
/// stores before any work.
struct Scratch {
    positions: Frame,
}

impl Scratch {
    fn new() -> Box<Self> {
        Box::new(Self {
            positions: [[0.0; PATCH]; 3],
        })
    }
}

/// Slot `k` of `frame`.
fn point_of(frame: &Frame, k: usize) -> Vec3 {
    Vec3::new(frame[0][k], frame[1][k], frame[2][k])
}

/// A frame axis's values four at a time (glam's `Vec4` is one SSE register; the compiler
/// turned the same loops over plain arrays into hundreds of shuffles).
#[inline(always)]
fn quads(values: &[f32; PATCH]) -> impl Iterator<Item = Vec4> + '_ {
    values.chunks_exact(4).map(Vec4::from_slice)
}

/// Zero if every value is finite, else NaN (`0 * inf` and `0 * NaN` are NaN).
fn poison(values: &[f32; PATCH]) -> f32 {
    quads(values)
        .fold(Vec4::ZERO, |sum, v| sum + v * 0.0)
        .element_sum()
}

/// The smallest and largest of finite `values`.
fn extremes(values: &[f32; PATCH]) -> [f32; 2] {
    let (low, high) = quads(values).fold((Vec4::INFINITY, Vec4::NEG_INFINITY), |(low, high), v| {
        (low.min(v), high.max(v))
    });
    [low.min_element(), high.max_element()]
}

/// The smaller of two finite floats, in one vector instruction (`f32::min` also handles NaN,
/// which keeps a loop of it from vectorising).
fn smaller(a: f32, b: f32) -> f32 {
    if b < a { b } else { a }
}

/// The larger of two finite floats, in one vector instruction (see [`smaller`]).
fn larger(a: f32, b: f32) -> f32 {
    if b > a { b } else { a }
}

fn bounds(points: &[Vec3]) -> (Vec3, Vec3) {
    points
        .iter()
        .fold((Vec3::INFINITY, Vec3::NEG_INFINITY), |(low, high), &p| {
            (low.min(p), high.max(p))
        })
}

/// The vertices of `positions` in the Morton order of where they lie: each run of [`PATCH`]
/// is a patch.
pub(super) fn morton_order(positions: &[Vec3]) -> Vec<u32> {
    let (low, high) = bounds(positions);
    let extent = (high - low).max_element().max(f32::MIN_POSITIVE);
    let mut order: Vec<(u64, u32)> = positions
        .iter()
        .enumerate()
        .map(|(v, &p)| (morton((p - low) / extent), v as u32))
        .collect();
    order.par_sort_unstable();
    order.into_iter().map(|(_, v)| v).collect()
}

/// Morton code of a point in the unit cube, 21 bits per axis.
fn morton(unit: Vec3) -> u64 {
    let spread = |x: f32| {
        let mut v = ((x.clamp(0.0, 1.0) * ((1 << 21) - 1) as f32) as u64) & 0x1f_ffff;
        v = (v | v << 32) & 0x1f_0000_0000_ffff;
        v = (v | v << 16) & 0x1f_0000_ff00_00ff;
        v = (v | v << 8) & 0x100f_00f0_0f00_f00f;
        v = (v | v << 4) & 0x10c3_0c30_c30c_30c3;
        (v | v << 2) & 0x1249_2492_4924_9249
    };
    spread(unit.x) | spread(unit.y) << 1 | spread(unit.z) << 2
}

#[cfg(test)]
pub(crate) mod tests {
    use rand::{RngExt, SeedableRng};

    use super::*;
    use crate::mesh::{GridPlane, grid};
    use crate::selfcollide::{
        Beside, BlockPoints, Idle, Resolver, SelfCollision, apply, exact_pairs, joined, resolve,
    };

    /// A [`Beside`] that keeps the zone it is offered, as a flag per place, and has no work.
    struct Recorded {
        places: usize,
        inside: std::sync::Mutex<Option<Vec<bool>>>,
        zone: std::sync::Mutex<Option<Zone>>,
    }

    impl Idle for Recorded {
        fn run_one(&self) -> bool {
            false
        }
    }

    impl Beside for Recorded {
        fn offer(&self, zone: Zone) {
            let mut inside = vec![false; self.places];
            zone.each_place(|place| inside[place as usize] = true);
            *self.inside.lock().expect("unpoisoned") = Some(inside);
            *self.zone.lock().expect("unpoisoned") = Some(zone);
        }
    }

    /// `resolver`'s moves of `points` (in mesh order: a vertex's place is itself), offering
    /// the zone beside them, and the zone if one was offered. Asserts that every vertex moved
    /// lay within its reach of the suspects, and that it holds every vertex moved and every
    /// vertex a spring joins to one (`what` names the case).
    fn moves_within_zone(
        resolver: &mut Resolver,
        points: &[Vec3],
        weights: &[f32],
        adjacency: &Adjacency,
        config: &SelfCollision,
        what: &str,
    ) -> (Vec<(u32, Vec3)>, Option<Vec<bool>>) {
        let recorded = Recorded {
            places: points.len(),
            inside: std::sync::Mutex::new(None),
            zone: std::sync::Mutex::new(None),
        };
        let moves = resolver.resolve_beside(points, weights, adjacency, config, Some(&recorded));
        let inside = recorded.inside.into_inner().expect("unpoisoned");
        if let Some(zone) = recorded.zone.into_inner().expect("unpoisoned") {
            // Where the vertex lay at the proof, not only its patch: within the reach.
            for &(v, _) in &moves {
                let at = points[v as usize];
                assert!(
                    zone.reaches(at),
                    "{what}: vertex {v} moved from beyond the reach"
                );
            }
        }
        if let Some(inside) = &inside {
            for &(v, _) in &moves {
                assert!(
                    inside[v as usize],
                    "{what}: vertex {v} moved outside the zone"
                );
                for &w in adjacency.neighbors_of(v) {
                    assert!(inside[w as usize], "{what}: {w}, joined to {v}, outside");
                }
            }
        }
        (moves, inside)
    }

    /// The springs of the generator's grid, `columns` vertices a row (the scripts place the
    /// vertices themselves).
    pub(crate) fn grid_springs(columns: u32, rows: u32) -> Vec<[u32; 2]> {
        let mesh = grid(columns, rows, [1.0, 1.0], GridPlane::Xz, glam::DVec3::ZERO);
        mesh.edges().iter().map(|e| [e.a, e.b]).collect()
    }

    /// The sheet at step `t` of `steps`: falling, turning about the vertical, its far part
    /// folded over a crease until it lies on the near part, every vertex jittered.
    pub(crate) fn folding_sheet(
        side: u32,
        spacing: f32,
        t: u32,
        steps: u32,
        rng: &mut impl rand::Rng,
    ) -> Vec<Vec3> {
        let crease = 0.55 * side as f32 * spacing;
        let angle = std::f32::consts::PI * (t as f32 / steps as f32).powf(0.7);
        let turn = glam::Quat::from_rotation_y(0.03 * t as f32);
        (0..side * side)
            .map(|v| {
                let (x, z) = ((v % side) as f32 * spacing, (v / side) as f32 * spacing);
                let folded = if x > crease {
                    let r = x - crease;
                    Vec3::new(crease + r * angle.cos(), r * angle.sin(), z)
                } else {
                    Vec3::new(x, 0.0, z)
                };
                let jitter = Vec3::new(rng.random(), rng.random(), rng.random()) - 0.5;
                turn * folded + Vec3::new(0.0, -0.004 * t as f32, 0.0) + 0.05 * spacing * jitter
            })
            .collect()
    }

    /// Two sheets, unconnected: the lower one at rest, the upper one turning and sinking
    /// onto it from four distances above to a third of the distance.
    fn stacked_sheets(
        side: u32,
        spacing: f32,
        t: u32,
        steps: u32,
        rng: &mut impl rand::Rng,
    ) -> Vec<Vec3> {
        // Apart when the patches are made, so no patch holds vertices of both sheets.
        let height = if t == 0 {
            1.0
        } else {
            spacing * (2.0 - 1.85 * t as f32 / steps as f32)
        };
        let turn = glam::Quat::from_rotation_y(0.01 * t as f32);
        (0..2 * side * side)
            .map(|v| {
                let (x, z) = (
                    ((v % side) as f32 - 0.5 * side as f32) * spacing,
                    ((v / side) % side) as f32 * spacing,
                );
                let jitter =
                    0.02 * spacing * (Vec3::new(rng.random(), rng.random(), rng.random()) - 0.5);
                if v < side * side {
                    Vec3::new(x, 0.0, z) + jitter
                } else {
                    turn * Vec3::new(x, 0.0, z) + Vec3::new(0.0, height, 0.0) + jitter
                }
            })
            .collect()
    }

    /// One sheet whose vertices slide in its plane along a few smooth waves that grow with
    /// `t`, until the sheet is squeezed to a fraction of its spacing in places.
    fn squeezed_sheet(
        side: u32,
        spacing: f32,
        t: u32,
        steps: u32,
        _: &mut impl rand::Rng,
    ) -> Vec<Vec3> {
        let amplitude = 0.25 * spacing * side as f32 / 6.0 * (t as f32 / steps as f32);
        (0..side * side)
            .map(|v| {
                let (x, z) = ((v % side) as f32 * spacing, (v / side) as f32 * spacing);
                let wave = |fx: f32, fz: f32, phase: f32| {
                    (std::f32::consts::TAU * (fx * x + fz * z) / (side as f32 * spacing)
                        + phase
                        + 0.05 * t as f32)
                        .sin()
                };
                let slide = Vec3::new(
                    wave(2.0, 0.5, 0.3) + 0.5 * wave(1.0, 3.0, 1.1),
                    0.2 * wave(1.5, 1.5, 2.0),
                    wave(0.5, 2.5, 0.7) + 0.5 * wave(3.0, 1.0, 2.9),
                );
                Vec3::new(x, -0.002 * t as f32, z) + amplitude * slide
            })
            .collect()
    }

    /// Positions stored last vertex first.
    struct Reversed(Vec<Vec3>);

    impl Points for Reversed {
        fn count(&self) -> usize {
            self.0.len()
        }

        fn place(&self, v: u32) -> u32 {
            self.0.len() as u32 - 1 - v
        }

        fn at(&self, place: u32) -> Vec3 {
            self.0[place as usize]
        }
    }

    /// Positions stored as a solver keeps them, in blocks of [`LANES`] per axis: here in the
    /// order of a culling's members, so every patch fills 8 blocks.
    struct Blocked {
        place_of: Vec<u32>,
        blocks: [Vec<[f32; LANES]>; 3],
    }

    impl Blocked {
        fn new(positions: &[Vec3], members: &[u32]) -> Self {
            let mut place_of = vec![0; members.len()];
            for (place, &v) in members.iter().enumerate() {
                place_of[v as usize] = place as u32;
            }
            let blocks = std::array::from_fn(|a| {
                members
                    .chunks(LANES)
                    .map(|run| {
                        std::array::from_fn(|l| {
                            run.get(l).map_or(0.0, |&v| positions[v as usize][a])
                        })
                    })
                    .collect()
            });
            Self { place_of, blocks }
        }
    }

    impl Blocked {
        /// The positions as a solver lends them.
        fn points(&self) -> BlockPoints<'_> {
            BlockPoints {
                places: &self.place_of,
                axes: self.blocks.each_ref().map(Vec::as_slice),
            }
        }
    }

    /// `moves` by vertex, each vertex's in the order made (its passes' order).
    fn by_vertex(moves: &[(u32, Vec3)]) -> Vec<(u32, Vec3)> {
        let mut moves = moves.to_vec();
        moves.sort_by_key(|&(v, _)| v);
        moves
    }

    #[test]
    fn culled_steps_give_the_same_moves_as_the_plain_passes() {
        type Script = fn(u32, f32, u32, u32, &mut rand_chacha::ChaCha8Rng) -> Vec<Vec3>;
        let (spacing, steps) = (0.01, 80);
        let config = SelfCollision {
            distance: 0.5 * spacing as f64,
            cell_size: spacing as f64,
            grids: 4,
            window: 4,
        };
        // Cells of about nine vertices of a sheet and windows of three: windows fill up, and
        // with the vertices of patches beside a suspect one (which a local pass must sort).
        let crowded = SelfCollision {
            cell_size: 3.0 * spacing as f64,
            window: 3,
            ..config
        };
        let scripts: [(&str, Script, u32, u32); 3] = [
            ("fold", folding_sheet, 40, 1),
            ("stacked", stacked_sheets, 32, 2),
            ("squeezed", squeezed_sheet, 48, 1),
        ];
        let (mut widened, mut backed_off) = (0, 0);
        let three = crate::selfcollide::pool_of(3);
        let runs = [config, crowded]
            .into_iter()
            .flat_map(|config| scripts.map(|script| (config, script)));
        for (config, (name, script, side, sheets)) in runs {
            let one = grid_springs(side, side);
            // Each sheet its own copy of the grid's springs.
            let ends: Vec<[u32; 2]> = (0..sheets)
                .flat_map(|s| {
                    one.iter()
                        .map(move |&[a, b]| [a + s * side * side, b + s * side * side])
                })
                .collect();
            let n = (sheets * side * side) as usize;
            let adjacency = Adjacency::from_springs(n, &ends);
            let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(5);
            let weights: Vec<f32> = (0..n)
                .map(|v| {
                    if v == 0 {
                        0.0
                    } else {
                        1.0 + rng.random::<f32>()
                    }
                })
                .collect();
            let mut resolver = Resolver::default();
            // Local passes however many vertices are suspect, keyed by 8 bits: runs of one
            // key then hold vertices of many cells, which the windows must pass over.
            let mut local = Resolver {
                local_at_most: 1,
                local_key_bits: |_| 8,
                ..Resolver::default()
            };
            // Reading the positions from a store in another order, as a solver's numbering
            // keeps them.
            let mut stored = Resolver::default();
            // Measuring patches straight from a solver's blocks, which hold them whole.
            let mut blocked = Resolver::default();
            // Offering the zone beside the passes (which then stay local), at any share of
            // suspects.
            let mut beside = Resolver {
                local_at_most: 1,
                ..Resolver::default()
            };
            let mut zones = 0;
            // Patches grouped by a layout unlike the points (the script's last step).
            let mut grouped = Resolver::default();
            grouped.group_by(&script(side, spacing, steps, steps, &mut rng.clone()));
            let mut members = Culling::default();
            let start = script(side, spacing, 0, steps, &mut rng.clone());
            members.prove(&start[..], &adjacency, config.distance as f32);
            let members = members.members;
            let mut moved_steps = 0;
            let mut suspects = Vec::new();
            for t in 0..=steps {
                let start = script(side, spacing, t, steps, &mut rng);
                let (mut plain, mut culled) = (start.clone(), start.clone());
                let mut local_only = start.clone();
                let expected = resolve(&mut plain, &weights, &adjacency, &config);
                let moves = resolver.resolve(&culled[..], &weights, &adjacency, &config);
                assert_eq!(moves, expected, "{name}, step {t}");
                apply(&mut culled, &moves);
                assert_eq!(culled, plain, "{name}, step {t}");
                // On three threads, whatever this machine has: the local passes then sort
                // every grid ahead and repair the orders (see `ahead`).
                let moves =
                    three.install(|| local.resolve(&local_only[..], &weights, &adjacency, &config));
                // A local pass lists its moves in its own sort's order.
                assert_eq!(
                    by_vertex(&moves),
                    by_vertex(&expected),
                    "{name}, step {t}, local"
                );
                apply(&mut local_only, &moves);
                assert_eq!(local_only, plain, "{name}, step {t}, local");
                let what = format!("{name}, step {t}, beside");
                let (moves, zone) = three.install(|| {
                    moves_within_zone(&mut beside, &start, &weights, &adjacency, &config, &what)
                });
                assert_eq!(by_vertex(&moves), by_vertex(&expected), "{what}");
                zones += usize::from(zone.is_some());
                let moves = grouped.resolve(&start[..], &weights, &adjacency, &config);
                assert_eq!(
                    by_vertex(&moves),
                    by_vertex(&expected),
                    "{name}, step {t}, grouped"
                );
                let stored_in_blocks = Blocked::new(&start, &members);
                let moves =
                    blocked.resolve(&stored_in_blocks.points(), &weights, &adjacency, &config);
                assert_eq!(moves, expected, "{name}, step {t}, blocked");
                let (by_block, by_copy) = (blocked.culling(), resolver.culling());
                assert!(
                    by_block.block_starts.iter().all(Option::is_some),
                    "{name}: not blocked"
                );
                assert!(by_copy.block_starts.iter().all(Option::is_none));
                // The same measurements from the blocks as from a copy of the points.
                let state = |patch: &Patch| (patch.centre, patch.spread, patch.low, patch.high);
                assert!(
                    by_block
                        .patches
                        .iter()
                        .zip(&by_copy.patches)
                        .all(|(a, b)| state(a) == state(b)),
                    "{name}, step {t}, blocked"
                );
                let reversed = Reversed(start.into_iter().rev().collect());
                let moves = stored.resolve(&reversed, &weights, &adjacency, &config);
                assert_eq!(moves, expected, "{name}, step {t}, stored in reverse");
                moved_steps += usize::from(!moves.is_empty());
                suspects.push(resolver.culling().suspects().len());
            }
            assert_ne!(
                grouped.culling().members,
                resolver.culling().members,
                "{name}: grouped alike"
            );
            let culling = resolver.culling();
            // Each script must show all three: steps proved clear, steps with pairs to push,
            // and passes over suspects alone.
            assert!(culling.cleared > 20, "{name}: cleared {}", culling.cleared);
            assert!(
                moved_steps > 5,
                "{name}: only {moved_steps} steps moved vertices"
            );
            let unproved = resolver.unproved_steps();
            assert_eq!(
                culling.cleared + culling.uncleared + unproved,
                u64::from(steps) + 1
            );
            backed_off += unproved;
            assert!(
                local.local_passes() >= 20,
                "{name}: {} local passes",
                local.local_passes()
            );
            widened += local.culling().widened;
            // Zones offered, which must have held the moves. (These sheets are too small for
            // one to leave much out: a zone reaches 3 passes' moves and widenings around the
            // suspects, about 14 spacings here.)
            assert!(zones > 5, "{name}: {zones} zones");
            eprintln!(
                "{name}: cleared {}, not {}, moved {moved_steps}, local passes {} (any share {}), \
                 suspects {:?}",
                culling.cleared,
                culling.uncleared,
                resolver.local_passes(),
                local.local_passes(),
                suspects
            );
        }
        // Moves past the margin, which make the suspects widen; proofs that did not help,
        // which make the next steps run without one.
        assert!(widened > 0);
        assert!(backed_off > 0);
    }

    /// Points of a lattice 1.4 distances apart (clear, beyond the margin), some with a twin
    /// almost on top of them, placed so that the first pass pushes the point 0.495 distances
    /// towards a lattice neighbour: within the distance of a vertex that no proof named, which
    /// a later grid's pass must find as the plain passes do.
    #[test]
    fn suspects_widen_to_where_an_earlier_pass_pushed_a_vertex() {
        let (distance, side) = (0.01f32, 20u32);
        let spacing = 1.4 * distance;
        let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(9);
        let mut points: Vec<Vec3> = (0..side * side * side)
            .map(|v| {
                let (i, j, k) = (v % side, (v / side) % side, v / (side * side));
                let jitter = Vec3::new(rng.random(), rng.random(), rng.random()) - 0.5;
                Vec3::new(i as f32, j as f32, k as f32) * spacing + 0.01 * distance * jitter
            })
            .collect();
        let lattice = points.len();
        let mut twinned = Vec::new();
        for _ in 0..300 {
            // Inside the lattice, so the neighbour pushed towards exists.
            let [i, j, k] = [0; 3].map(|_| rng.random_range(1..side - 1));
            let a = (k * side + j) * side + i;
            let mut towards = Vec3::ZERO;
            towards[rng.random_range(0..3)] = if rng.random() { 1.0 } else { -1.0 };
            points.push(points[a as usize] - 0.01 * distance * towards);
            twinned.push(a);
        }
        let adjacency = Adjacency::from_springs(points.len(), &[]);
        let weights = vec![1.0; points.len()];
        let config = SelfCollision {
            distance: f64::from(distance),
            cell_size: 2.0 * f64::from(distance),
            grids: 4,
            window: 4,
        };
        let mut plain = points.clone();
        let expected = resolve(&mut plain, &weights, &adjacency, &config);
        let mut local = Resolver {
            local_at_most: 1,
            ..Resolver::default()
        };
        let points_before = points.clone();
        let moves = local.resolve(&points[..], &weights, &adjacency, &config);
        assert_eq!(moves, expected);
        apply(&mut points, &moves);
        assert_eq!(points, plain);
        // The case this test is for: lattice points with no twin that the passes moved.
        let bystanders = expected
            .iter()
            .filter(|(v, _)| (*v as usize) < lattice && !twinned.contains(v))
            .count();
        assert!(bystanders > 5, "{bystanders} bystanders moved");
        assert_eq!(local.local_passes(), 4);
        // The zone offered beside the passes holds the bystanders too.
        let mut beside = Resolver::default();
        let (moves, zone) = moves_within_zone(
            &mut beside,
            &points_before,
            &weights,
            &adjacency,
            &config,
            "lattice",
        );
        assert_eq!(moves, expected);
        assert!(zone.is_some(), "no zone offered");
        assert_eq!(beside.local_passes(), 4);
    }

    /// Checks the proof of `positions` against the exact search: clear exactly when no
    /// unjoined pair is within `distance`, and otherwise every vertex within the distance and
    /// the margin of an unjoined one suspect, and no vertex suspect without one within a
    /// little more (the rounding's margin). `expected`: whether the state is clear (the
    /// test's own).
    fn check_proof(
        culling: &mut Culling,
        positions: &[Vec3],
        adjacency: &Adjacency,
        distance: f32,
        expected: bool,
    ) {
        let close = exact_pairs(positions, adjacency, f64::from(distance));
        assert_eq!(close.is_empty(), expected, "the test's own state");
        let proof = culling.prove(positions, adjacency, distance);
        assert_eq!(proof == Proof::Clear, expected);
        if !expected {
            assert_eq!(proof, Proof::Local);
            let within =
                |share: f32| exact_pairs(positions, adjacency, f64::from(distance * (1.0 + share)));
            for &(a, b) in &within(MARGIN) {
                assert!(culling.is_suspect(a) && culling.is_suspect(b), "{a} {b}");
            }
            let wide = within(MARGIN + 0.01);
            for &v in culling.suspects() {
                assert!(
                    wide.iter().any(|&(a, b)| a == v || b == v),
                    "suspect {v} has no close pair"
                );
            }
            // The flags say the same as the list: none left over from an earlier proof.
            let listed: std::collections::HashSet<u32> =
                culling.suspects().iter().copied().collect();
            for v in 0..positions.len() as u32 {
                assert_eq!(culling.is_suspect(v), listed.contains(&v), "vertex {v}");
            }
        }
    }

    /// A position that is not finite (NaN, or infinite either way), in any slot of any patch
    /// and on any axis, makes the proof give up; finite positions then prove as before.
    #[test]
    fn a_position_that_is_not_finite_proves_nothing() {
        let distance = 0.004f32;
        let (adjacency, sheet) = flat_squeezed_grid(24, 24, 0.01, 0.02);
        let mut culling = Culling::default();
        check_proof(&mut culling, &sheet, &adjacency, distance, true);
        let odd = [f32::NAN, f32::INFINITY, f32::NEG_INFINITY];
        for (k, v) in [0, 7, 130, 333, 575].into_iter().enumerate() {
            let mut broken = sheet.clone();
            broken[v][k % 3] = odd[k % 3];
            assert_eq!(
                culling.prove(broken.as_slice(), &adjacency, distance),
                Proof::Nothing
            );
            check_proof(&mut culling, &sheet, &adjacency, distance, true);
        }
    }

    /// A patch's box is its references' box moved by its displacements' (not its points'
    /// own), so it must still hold every point, through renewals and the rounding of
    /// coordinates far from the origin; the far pairs and the covering rely on it.
    #[test]
    fn every_patch_box_holds_its_points() {
        let (side, spacing, steps) = (40u32, 0.01f32, 60u32);
        let adjacency = Adjacency::from_springs((side * side) as usize, &grid_springs(side, side));
        for origin in [Vec3::ZERO, Vec3::new(1000.0, -3000.0, 250.0)] {
            let mut culling = Culling::default();
            let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(17);
            let (mut renewed, mut displaced) = (0.0, 0);
            for t in 0..=steps {
                let sheet: Vec<Vec3> = folding_sheet(side, spacing, t, steps, &mut rng)
                    .into_iter()
                    .map(|x| x + origin)
                    .collect();
                let proof = culling.prove(&sheet[..], &adjacency, 0.5 * spacing);
                assert_ne!(proof, Proof::Nothing, "step {t}");
                for (p, patch) in culling.patches.iter().enumerate() {
                    for &v in culling.members_of(p as u32) {
                        let x = sheet[v as usize];
                        assert!(
                            x.cmpge(patch.low).all() && x.cmple(patch.high).all(),
                            "origin {origin}, step {t}: vertex {v} at {x} outside patch {p}'s \
                             box {}..{}",
                            patch.low,
                            patch.high
                        );
                    }
                }
                renewed = culling.patches.iter().map(|p| p.renewed).sum::<f64>();
                displaced += culling.patches.iter().filter(|p| p.spread > 0.0).count();
            }
            // Both kinds of measurement: after renewals and between them.
            assert!(renewed > 0.0, "origin {origin}: no patch renewed");
            assert!(
                displaced > 0,
                "origin {origin}: every patch on its references"
            );
        }
    }

    /// Each node's box is the smallest that holds its two halves' (a leaf's: its patch's),
    /// also where `refit` fits the halves side by side (a sheet of more than
    /// [`REFIT_TASK_PATCHES`] patches, on 3 threads).
    #[test]
    fn each_node_box_is_the_smallest_holding_its_halves() {
        let (side, spacing, steps) = (192u32, 0.005f32, 4u32);
        let adjacency = Adjacency::from_springs((side * side) as usize, &grid_springs(side, side));
        let pool = crate::selfcollide::pool_of(3);
        let mut culling = Culling::default();
        let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(5);
        for t in 0..=steps {
            let sheet = folding_sheet(side, spacing, t, steps, &mut rng);
            pool.install(|| culling.prove(&sheet[..], &adjacency, 0.5 * spacing));
            assert!(culling.patch_count() > REFIT_TASK_PATCHES as usize);
            for (i, node) in culling.nodes.iter().enumerate() {
                let fitted = match node.children {
                    None => {
                        let patch = &culling.patches[node.first as usize];
                        (patch.low, patch.high)
                    }
                    Some([a, b]) => {
                        let (a, b) = (&culling.nodes[a as usize], &culling.nodes[b as usize]);
                        (a.low.min(b.low), a.high.max(b.high))
                    }
                };
                assert_eq!((node.low, node.high), fitted, "step {t}, node {i}");
            }
        }
    }

    /// A contact that moves from place to place, step after step: each proof's suspects are
    /// where the contact is then, with none left over from the one before.
    #[test]
    fn suspects_follow_the_contact_from_place_to_place() {
        let (columns, distance) = (48u32, 0.004f32);
        let (adjacency, sheet) = flat_squeezed_grid(columns, 48, 0.01, 2.0 * distance);
        let mut culling = Culling::default();
        check_proof(&mut culling, &sheet, &adjacency, distance, true);
        for v in [
            5 * columns + 5,
            40 * columns + 40,
            5 * columns + 40,
            5 * columns + 5,
        ] {
            // Half a distance from its unjoined neighbour two along.
            let mut touching = sheet.clone();
            touching[v as usize].x += 1.5 * distance;
            check_proof(&mut culling, &touching, &adjacency, distance, false);
        }
    }

    /// The generator grid's springs, and [`squeezed_grid`]'s positions at height 0.
    fn flat_squeezed_grid(
        columns: u32,
        rows: u32,
        spacing: f32,
        gap: f32,
    ) -> (Adjacency, Vec<Vec3>) {
        let adjacency =
            Adjacency::from_springs((columns * rows) as usize, &grid_springs(columns, rows));
        (adjacency, squeezed_grid(columns, rows, spacing, gap, 0.0))
    }

    /// A grid of `columns` x `rows` squeezed along x until each vertex's unjoined neighbour
    /// two along lies `gap` away, at height `y`.
    fn squeezed_grid(columns: u32, rows: u32, spacing: f32, gap: f32, y: f32) -> Vec<Vec3> {
        let squeeze = gap / (2.0 * spacing);
        (0..columns * rows)
            .map(|v| {
                let (j, i) = (v % columns, v / columns);
                Vec3::new(j as f32 * spacing * squeeze, y, i as f32 * spacing)
            })
            .collect()
    }

    /// Every verdict of `clear` against the exact search, on a grid squeezed along x until
    /// each vertex's unjoined neighbour two along lies 1.1 distances away: one vertex nudged,
    /// or one patch moved whole, by 0.15 distances makes contact that only the patch's spread,
    /// or only its drift from the patch beside it, can show (neither renews the patch).
    #[test]
    fn clear_answers_whether_any_unjoined_pair_is_closer_than_the_distance() {
        let (rows, spacing, distance) = (32u32, 0.01f32, 0.005f32);
        let squeeze = 1.1 * distance / (2.0 * spacing);
        // As wide as it is deep once squeezed, so patches hold parts of rows.
        let columns = (rows as f32 / squeeze) as u32;
        let adjacency =
            Adjacency::from_springs((columns * rows) as usize, &grid_springs(columns, rows));
        let base =
            |t: u32| squeezed_grid(columns, rows, spacing, 1.1 * distance, -0.001 * t as f32);
        let mut culling = Culling::default();
        let mut t = 0;
        let check = |culling: &mut Culling, positions: &[Vec3], expected: bool| {
            check_proof(culling, positions, &adjacency, distance, expected);
        };
        for _ in 0..4 {
            t += 1;
            check(&mut culling, &base(t), true);
        }
        let nudge = Vec3::new(0.15 * distance, 0.0, 0.0);
        for v in [3 * columns + 5, 17 * columns + 60, 30 * columns + 100] {
            t += 1;
            let mut nudged = base(t);
            nudged[v as usize] += nudge;
            check(&mut culling, &nudged, false);
            t += 1;
            check(&mut culling, &base(t), true);
        }
        for patch in [5, 20, 40] {
            t += 1;
            let mut moved = base(t);
            for &v in culling.members_of(patch) {
                moved[v as usize] -= nudge;
            }
            check(&mut culling, &moved, false);
            t += 1;
            check(&mut culling, &base(t), true);
        }
    }

    /// A patch that bends as it moves (enough to renew its references) slides into the patch
    /// beside it in one step: the gaps its near pairs measured before carry over the renewal
    /// (less its spread), and their drift, counted from where the patch was built, still
    /// shows the contact.
    /// Scattered points, a short last patch, and springs joining each point to its nearest
    /// other (the pairs closest_unjoined must pass over) and to a few at random: every pair
    /// of patches gives the smallest distance of every unjoined pair, bit for bit.
    #[test]
    fn closest_unjoined_is_the_smallest_distance_of_any_unjoined_pair() {
        let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(3);
        let n = 4 * PATCH + 44;
        let points: Vec<Vec3> = (0..n)
            .map(|_| Vec3::new(rng.random(), rng.random(), rng.random()))
            .collect();
        let mut ends = Vec::new();
        for (a, &x) in points.iter().enumerate() {
            let nearest = (0..n)
                .filter(|&b| b != a)
                .min_by(|&b, &c| x.distance(points[b]).total_cmp(&x.distance(points[c])))
                .unwrap();
            ends.push([a as u32, nearest as u32]);
            ends.push([a as u32, rng.random_range(0..n as u32)]);
        }
        ends.retain(|[a, b]| a != b);
        let adjacency = Adjacency::from_springs(n, &ends);
        let mut culling = Culling::default();
        culling.prove(&points[..], &adjacency, 0.01);
        let count = n.div_ceil(PATCH) as u32;
        for p in 0..count {
            for q in 0..count {
                let found =
                    culling.closest_unjoined([p, q], |r| culling.current(&points[..], r), 0.0);
                let mut expected = f32::INFINITY;
                for &v in culling.members_of(p) {
                    for &w in culling.members_of(q) {
                        if v != w && !joined(&adjacency, v, w) {
                            let d = points[w as usize] - points[v as usize];
                            expected = expected.min(d.x * d.x + d.y * d.y + d.z * d.z);
                        }
                    }
                }
                assert_eq!(found, expected.sqrt(), "patches {p} and {q}");
            }
        }
    }

    #[test]
    fn patches_are_numbered_by_their_first_place() {
        // Stored last vertex first, so places run against the vertices' Morton order; the
        // count leaves a short last patch.
        let side = 37u32;
        let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(5);
        let points = Reversed(folding_sheet(side, 0.01, 0, 10, &mut rng));
        let n = points.count();
        let adjacency = Adjacency::from_springs(n, &grid_springs(side, side));
        let mut culling = Culling::default();
        culling.prove(&points, &adjacency, 0.005);
        let mut seen = culling.members.clone();
        seen.sort_unstable();
        assert!(
            seen.iter().copied().eq(0..n as u32),
            "every vertex in one patch"
        );
        let count = n.div_ceil(PATCH) as u32;
        let firsts: Vec<u32> = (0..count)
            .map(|p| points.place(culling.members_of(p)[0]))
            .collect();
        for p in 0..count {
            let places: Vec<u32> = culling
                .members_of(p)
                .iter()
                .map(|&v| points.place(v))
                .collect();
            assert!(places.is_sorted(), "patch {p}'s members in place order");
        }
        assert_eq!(culling.members_of(count - 1).len(), n % PATCH);
        assert!(firsts[..count as usize - 1].is_sorted(), "{firsts:?}");
        // The hierarchy's leaves name every patch once, in their Morton order.
        let mut leaves: Vec<u32> = culling
            .nodes
            .iter()
            .filter(|node| node.children.is_none())
            .map(|node| node.first)
            .collect();
        assert!(leaves != (0..count).collect::<Vec<_>>(), "{leaves:?}");
        leaves.sort_unstable();
        assert!(leaves.into_iter().eq(0..count));
        // Each patch's places are those its vertices' positions group, not a run of places.
        assert!((0..count - 1).any(|p| {
            let places = culling.members_of(p).iter().map(|&v| points.place(v));
            places.max().unwrap() - firsts[p as usize] >= PATCH as u32
        }));
    }

    /// A pair of patches that no springs join is kept as a near pair, its gap cached, from
    /// when the far search first measures it until their boxes part: a sheet folded onto
    /// itself, then opened out flat again. Every proof stays exact (see `check_proof`).
    #[test]
    fn far_pairs_are_adopted_until_their_boxes_part() {
        let (side, spacing, steps) = (40u32, 0.01f32, 40u32);
        let distance = 0.5 * spacing;
        let adjacency = Adjacency::from_springs((side * side) as usize, &grid_springs(side, side));
        let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(3);
        let frames: Vec<Vec<Vec3>> = (0..=steps)
            .map(|t| folding_sheet(side, spacing, t, steps, &mut rng))
            .collect();
        let mut culling = Culling::default();
        let adopted = |culling: &Culling| -> Vec<[u32; 2]> {
            let pairs: Vec<[u32; 2]> = culling.near[culling.joined_pairs..]
                .iter()
                .map(|pair| pair.patches)
                .collect();
            // Each listed under its lower patch, and none that springs join.
            let listed: usize = culling.adopted.iter().map(Vec::len).sum();
            assert_eq!(listed, pairs.len());
            for &[p, q] in &pairs {
                assert!(p < q && culling.adopted[p as usize].contains(&q));
                let joined = culling.near_offsets[p as usize] as usize
                    ..culling.near_offsets[p as usize + 1] as usize;
                assert!(!culling.near_patches[joined].contains(&q));
            }
            pairs
        };
        let apart = |culling: &Culling, [p, q]: [u32; 2]| {
            let (a, b) = (&culling.patches[p as usize], &culling.patches[q as usize]);
            box_gap((a.low, a.high), (b.low, b.high))
        };
        let mut folded = Vec::new();
        for positions in frames.iter().chain(frames.iter().rev()) {
            let clear = exact_pairs(positions, &adjacency, f64::from(distance)).is_empty();
            check_proof(&mut culling, positions, &adjacency, distance, clear);
            // Each pair once: the far search measures none of those adopted.
            let pairs: std::collections::HashSet<[u32; 2]> =
                culling.near.iter().map(|pair| pair.patches).collect();
            assert_eq!(pairs.len(), culling.near.len());
            // Every pair of patches left to the far search has its boxes out of reach: those
            // that came within it were found, from where the last walk stopped, and adopted.
            let (count, reach) = (
                culling.patches.len() as u32,
                culling.clear_at + culling.margin,
            );
            for p in 0..count {
                for q in p + 1..count {
                    assert!(culling.near(p, q) || apart(&culling, [p, q]) >= reach);
                }
            }
            if std::ptr::eq(positions, &frames[steps as usize]) {
                folded = adopted(&culling);
            }
        }
        for _ in 0..PARTING_EVERY {
            check_proof(&mut culling, &frames[0], &adjacency, distance, true);
        }
        // Found from where the walks stopped: the hierarchy was not walked from its root each step.
        assert!(
            8 * culling.walks < culling.proofs,
            "{} walks",
            culling.walks
        );
        // Opened out, the pairs the fold brought together have parted and are given back;
        // those whose boxes still reach each other on the flat sheet (its patches are runs of
        // a Morton order over 40 columns, not squares) stay.
        let parted = culling.clear_at + culling.margin;
        let flat = adopted(&culling);
        assert!(
            flat.iter()
                .all(|&pair| apart(&culling, pair) < PARTED * parted)
        );
        let given_back = folded.iter().filter(|pair| !flat.contains(pair)).count();
        assert!(given_back > 0, "{} adopted at the fold", folded.len());
        for &pair in &folded {
            if apart(&culling, pair) >= PARTED * parted {
                assert!(!flat.contains(&pair), "{pair:?} parted");
            }
        }
    }

    #[test]
    fn gaps_carry_over_renewals_to_the_contact() {
        let (side, spacing, distance) = (32u32, 0.01f32, 0.005f32);
        let adjacency = Adjacency::from_springs((side * side) as usize, &grid_springs(side, side));
        let base = squeezed_grid(side, side, spacing, 2.0 * spacing, 0.0);
        let mut culling = Culling::default();
        check_proof(&mut culling, &base, &adjacency, distance, true);
        let inner =
            |v: u32| (4..side - 4).contains(&(v % side)) && (4..side - 4).contains(&(v / side));
        let patch = (0..culling.patches.len() as u32)
            .find(|&p| {
                let members = culling.members_of(p);
                members.len() == PATCH && members.iter().all(|&v| inner(v))
            })
            .expect("an inner patch");
        // 3.3 distances along -x: its vertices 0.7 distances (and the bend's 0.5 up or down)
        // from those of the patch beside it two along; half of it up and half down by half a
        // distance, past an eighth of its slack (the diagonal's 2.83 distances less one).
        let mut moved = base.clone();
        for (k, &v) in culling.members_of(patch).iter().enumerate() {
            let up = if k < PATCH / 2 { 0.5 } else { -0.5 };
            moved[v as usize] += Vec3::new(-3.3, up, 0.0) * distance;
        }
        check_proof(&mut culling, &moved, &adjacency, distance, false);
        assert!(
            culling.patches[patch as usize].renewed > 0.0,
            "the patch renewed its references"
        );
    }
}
