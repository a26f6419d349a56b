//! The per-chunk kernels of one time step, written as 8-lane loops that LLVM turns into SIMD.
//!
//! Each public kernel handles a contiguous chunk of slices (or spring rows). It is written once,
//! generic over [`Simd`], and runs with AVX2 where the CPU has it, else portably; no kernel
//! reassociates, and both round a fused multiply-add once ([`Simd::mul_add`]), so both give
//! bit-identical results.
//!
//! Spring force (paper eq. 1, sign of eq. 4) on vertex `i` from spring `ij`:
//! `D_ij (1 - |l0_ij| / |l_ij|) (x_j - x_i)`, as `(D_ij - D_ij |l0_ij| / |l_ij|) (x_j - x_i)`.
//! Swapping `i` and `j` negates `x_j - x_i` exactly in floating point and leaves the scale
//! unchanged, so the force of a spring computed from either end (gather) or once and negated
//! (scatter) is the same number.
//!
//! Verlet with damping (eq. 3-4) in delta form. The state is `x` and `d = x - x_prev`; with
//! precomputed `a = dt^2 / m` and `v = 1 - c dt / m` (both 0 for pinned and padding vertices):
//! `d(t+dt) = v d + a F_springs + g dt^2`, `x(t+dt) = x + d(t+dt)`; pinned vertices keep `x`.
//! This is eq. 3 rearranged, but in float32 it matters: `x - x_prev` and `a F dt^2` are far
//! smaller than `x`, and storing `x_prev` rounds them to the ulp of `x` every step (a free fall
//! from 2 m at dt = 1e-4 s loses 21% of its distance that way). Stored as `d` they keep their
//! own precision, and only `x + d` rounds, without feeding back into the velocity.

pub use crate::lanes::{Lanes, Soa};
use std::ops::Range;

use crate::layout::{LANES, Slices};
#[cfg(target_arch = "x86_64")]
use crate::simd::Avx2;
pub use crate::simd::{Block, Point};
use crate::simd::{POINT_BYTES, Portable, Simd, point_at_slot, point_offset};
pub use crate::view::Positions;
use crate::view::{Floats, Points};

/// Spring stiffness per entry, or one value for all. A uniform stiffness is one row read with
/// stride 0: branch-free in the kernels, and it saves a memory stream.
#[derive(Clone, Debug)]
pub struct Stiffness {
    rows: Vec<Block>,
    stride: usize,
}

impl Stiffness {
    pub fn uniform(value: f32) -> Self {
        Self {
            rows: vec![[value; LANES]],
            stride: 0,
        }
    }

    pub fn per_entry(rows: Vec<Block>) -> Self {
        Self { rows, stride: 1 }
    }

    #[inline(always)]
    fn row(&self, row: usize) -> &Block {
        &self.rows[row * self.stride]
    }

    /// The one row of a uniform stiffness.
    #[inline(always)]
    fn uniform_row(&self) -> Option<&Block> {
        (self.stride == 0).then(|| &self.rows[0])
    }

    /// Sets the stiffness of `entries` to zero (springs that tore) in a table of `entry_count`
    /// entries; a uniform stiffness becomes one per entry first.
    pub fn zero_entries(&mut self, entries: impl Iterator<Item = usize>, entry_count: usize) {
        if self.stride == 0 {
            self.rows = vec![self.rows[0]; entry_count.div_ceil(LANES)];
            self.stride = 1;
        }
        for entry in entries {
            self.rows[entry / LANES][entry % LANES] = 0.0;
        }
    }

    /// Bytes streamed per step (a uniform value stays in L1).
    pub fn bytes(&self) -> usize {
        self.stride * std::mem::size_of_val(self.rows.as_slice())
    }
}

/// Rows of 8 index entries (an index, plus flag bits above `mask` such as [`B_END`]).
///
/// A row whose masked indices run consecutively (`i, i+1, ..., i+7`) with the same flags in
/// every lane, as interior rows of a regularly numbered mesh do, is stored as its first entry
/// and loads with one vector load; any other row is stored whole and loads with a gather. That
/// cuts the index stream of a grid from 32 to 5 bytes per row.
///
/// When most rows load lane by lane (an irregular mesh's), every row is stored whole instead,
/// row by row, each entry as the byte offset of its point (its [`point_slot`] times 16, flags
/// kept): the kernels then read row after row with no lookup, no branch and no shift per
/// lane, which took the irregular bench mesh's steps from 0.24 to 0.22 ms (gather) and from
/// 0.37 to 0.29 ms (scatter; see the performance log).
#[derive(Clone, Debug, Default)]
pub struct IndexRows {
    /// Per row: its lane-0 entry if contiguous, else its position in `gathered`. When the
    /// rows are point offsets: empty, or with [`RowForm::Points`] the lane-0 entry of a
    /// contiguous row and 0 for others.
    head: Vec<u32>,
    contiguous: Vec<bool>,
    gathered: Vec<[u32; LANES]>,
    /// Whether `gathered` holds every row as point offsets.
    point_offsets: bool,
    mask: u32,
}

/// How [`IndexRows`] stores its rows.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum RowForm {
    /// Contiguous rows as their first entry, the others whole.
    Runs,
    /// Every row as point offsets when fewer than half are contiguous, else as runs: a table
    /// the kernels read from points when most rows are gathered.
    PointsIfGathered,
    /// Every row as point offsets: a scatter spring end whose rows the force pass reads from
    /// points, the contiguous ones from the axes.
    Points,
}

impl IndexRows {
    /// Flags rows whose masked indices run consecutively and stay below `limit`, and stores
    /// them as `form` says; point offsets only where every offset fits below the flags.
    pub fn new(rows: Vec<[u32; LANES]>, mask: u32, limit: usize, form: RowForm) -> Self {
        let contiguous: Vec<bool> = rows
            .iter()
            .map(|r| {
                let first = (r[0] & mask) as usize;
                first + LANES <= limit
                    && (0..LANES).all(|lane| {
                        (r[lane] & mask) as usize == first + lane && r[lane] & !mask == r[0] & !mask
                    })
            })
            .collect();
        let mut table = Self {
            contiguous,
            mask,
            ..Self::default()
        };
        let offsets_fit = limit as u64 * u64::from(POINT_BYTES) <= u64::from(mask) + 1;
        let points = match form {
            RowForm::Runs => false,
            RowForm::PointsIfGathered => table.mostly_gathered(),
            RowForm::Points => true,
        };
        if points && offsets_fit {
            let offset = |entry: u32| point_offset(entry, mask) | (entry & !mask);
            let first = |(r, &run): (&[u32; LANES], &bool)| if run { r[0] & mask } else { 0 };
            if form == RowForm::Points {
                // Read by the force pass (`IndexRows::runs`).
                table.head = rows.iter().zip(&table.contiguous).map(first).collect();
            }
            table.gathered = rows.into_iter().map(|r| r.map(offset)).collect();
            table.point_offsets = true;
            return table;
        }
        for (r, &contiguous) in rows.iter().zip(&table.contiguous) {
            if contiguous {
                table.head.push(r[0]);
            } else {
                table.head.push(table.gathered.len() as u32);
                table.gathered.push(*r);
            }
        }
        table
    }

    pub fn len(&self) -> usize {
        self.contiguous.len()
    }

    pub fn is_empty(&self) -> bool {
        self.contiguous.is_empty()
    }

    /// The 8 entries of `row`.
    pub fn row(&self, row: usize) -> [u32; LANES] {
        if self.point_offsets {
            let mask = self.mask;
            return self.gathered[row]
                .map(|e| point_at_slot((e & mask) / POINT_BYTES) | (e & !mask));
        }
        let head = self.head[row];
        if self.contiguous[row] {
            std::array::from_fn(|lane| head + lane as u32)
        } else {
            self.gathered[head as usize]
        }
    }

    /// Every row as point offsets (see the type's docs), if stored so.
    #[inline(always)]
    pub fn point_offsets(&self) -> Option<&[[u32; LANES]]> {
        self.point_offsets.then_some(self.gathered.as_slice())
    }

    /// Per row of a table stored in [`RowForm::Points`], its first index if its indices
    /// run consecutively (below the `limit` it was built with), else `None`.
    #[inline(always)]
    fn runs(&self, rows: Range<usize>) -> impl Iterator<Item = Option<u32>> {
        let heads = &self.head[rows.clone()];
        let runs = &self.contiguous[rows];
        heads.iter().zip(runs).map(|(&h, &run)| run.then_some(h))
    }

    pub fn bytes(&self) -> usize {
        if self.point_offsets {
            let runs = if self.head.is_empty() {
                0
            } else {
                std::mem::size_of_val(self.head.as_slice()) + self.contiguous.len()
            };
            return std::mem::size_of_val(self.gathered.as_slice()) + runs;
        }
        std::mem::size_of_val(self.head.as_slice())
            + self.contiguous.len()
            + std::mem::size_of_val(self.gathered.as_slice())
    }

    /// Share of rows whose indices run consecutively.
    pub fn contiguous_share(&self) -> f64 {
        self.contiguous.iter().filter(|c| **c).count() as f64 / self.len().max(1) as f64
    }

    /// Whether most rows load lane by lane (an irregular mesh's): the values they gather are
    /// then worth keeping as points, one load a lane.
    pub fn mostly_gathered(&self) -> bool {
        self.contiguous_share() < 0.5
    }
}

/// Per-entry values in rows of 8. A row whose 8 values are the same, as most rows of a regular
/// mesh's rest lengths are (a grid has one rest length per direction), is stored as that value:
/// 5 bytes read per row instead of 32, a third of the bytes a grid's step streams. A table with
/// few such rows (an irregular mesh's) stores every row whole and reads nothing more.
#[derive(Clone, Debug, Default)]
pub struct ValueRows {
    /// Per row, when compacted: the value's bits if the row is uniform, else its position in
    /// `whole`. Empty when every row is stored whole.
    head: Vec<u32>,
    uniform: Vec<bool>,
    whole: Vec<Block>,
}

impl ValueRows {
    /// Compacts `rows` if at least a quarter of them are uniform (bit for bit).
    pub fn new(rows: Vec<Block>) -> Self {
        let is_uniform = |r: &Block| r.iter().all(|v| v.to_bits() == r[0].to_bits());
        if 4 * rows.iter().filter(|r| is_uniform(r)).count() < rows.len() {
            return Self {
                whole: rows,
                ..Self::default()
            };
        }
        let mut table = Self::default();
        for r in rows {
            let uniform = is_uniform(&r);
            table.uniform.push(uniform);
            if uniform {
                table.head.push(r[0].to_bits());
            } else {
                table.head.push(table.whole.len() as u32);
                table.whole.push(r);
            }
        }
        table
    }

    pub fn len(&self) -> usize {
        if self.head.is_empty() {
            self.whole.len()
        } else {
            self.head.len()
        }
    }

    pub fn is_empty(&self) -> bool {
        self.len() == 0
    }

    /// The 8 values of `row`.
    pub fn row(&self, row: usize) -> Block {
        if self.head.is_empty() {
            self.whole[row]
        } else if self.uniform[row] {
            [f32::from_bits(self.head[row]); LANES]
        } else {
            self.whole[self.head[row] as usize]
        }
    }

    /// Every row, when all are stored whole.
    #[inline(always)]
    fn whole_rows(&self) -> Option<&[Block]> {
        self.head.is_empty().then_some(self.whole.as_slice())
    }

    #[inline(always)]
    fn load<S: Simd>(&self, simd: S, row: usize) -> S::V {
        if self.head.is_empty() {
            simd.load(&self.whole[row])
        } else if self.uniform[row] {
            simd.splat(f32::from_bits(self.head[row]))
        } else {
            simd.load(&self.whole[self.head[row] as usize])
        }
    }

    /// Bytes read per pass over every row.
    pub fn bytes(&self) -> usize {
        std::mem::size_of_val(self.head.as_slice())
            + self.uniform.len()
            + std::mem::size_of_val(self.whole.as_slice())
    }

    /// Share of rows stored as one value.
    pub fn uniform_share(&self) -> f64 {
        self.uniform.iter().filter(|u| **u).count() as f64 / self.len().max(1) as f64
    }
}

/// Point-centric (PCA) table: for each entry, the neighbour and the spring's constants.
#[derive(Clone, Debug)]
pub struct GatherTable {
    pub slices: Slices,
    /// Per entry: internal index of the neighbour (the lane's own vertex for padding).
    pub neighbor: IndexRows,
    /// Per entry: rest length, m (0 for padding).
    pub rest_length: ValueRows,
    pub stiffness: Stiffness,
}

/// Edge-centric (ECA) springs, in rows of 8: the springs and any zero-force padding between
/// them (an irregular mesh's blocks end in whole rows), then the last row's padding.
#[derive(Clone, Debug)]
pub struct SpringTable {
    pub a: IndexRows,
    pub b: IndexRows,
    pub rest_length: ValueRows,
    pub stiffness: Stiffness,
    /// Slots before the last row's padding.
    pub slots: usize,
    /// Whether the force pass stores each spring's stretch `(d, k)` as a point instead of its
    /// force `k d` ([`Simd::store_stretches`]): where gather sums fused (see
    /// `tables::sums_fused`). Only with forces as points.
    pub stretches: bool,
}

/// Scatter's per-spring forces, as its force pass writes them and its accumulation reads them.
/// The last row stays zero for padding entries.
#[derive(Clone, Debug)]
pub enum SpringForces {
    /// Three axes of blocks: a structured mesh's incidence rows run consecutively and load
    /// with vector loads.
    Axes(Soa),
    /// One point per spring slot, in rows of 8: an irregular mesh's incidence rows are
    /// gathered lane by lane, and each lane then takes one load instead of three.
    Points(Vec<[Point; LANES]>),
}

impl SpringForces {
    /// Points where the incidence table reads them ([`IncidenceTable::forces_as_points`]).
    pub fn for_incidence(incidence: &IncidenceTable, spring_rows: usize) -> Self {
        if incidence.forces_as_points() {
            Self::Points(vec![[[0.0; 4]; LANES]; spring_rows + 1])
        } else {
            Self::Axes(Soa::zeros(spring_rows + 1))
        }
    }

    pub fn bytes(&self) -> usize {
        match self {
            Self::Axes(axes) => axes.bytes(),
            Self::Points(rows) => std::mem::size_of_val(rows.as_slice()),
        }
    }

    /// The forces as the accumulation reads them.
    pub fn view(&self) -> ForcesView<'_> {
        match self {
            Self::Axes(axes) => {
                ForcesView::Axes(axes.axes().map(|a| Floats::new(a.as_flattened())))
            }
            Self::Points(rows) => ForcesView::Points(Points::new(rows.as_flattened())),
        }
    }
}

/// Scatter's spring forces as the accumulation reads them: pointers, so that a schedule may
/// sum some rows while other threads write others (see `crate::blocks`).
#[derive(Clone, Copy, Debug)]
pub enum ForcesView<'a> {
    Axes([Floats<'a>; 3]),
    Points(Points<'a>),
}

/// Where a chunk of scatter's force pass writes its rows.
#[derive(Debug)]
pub enum ForceRows<'a> {
    Axes([&'a mut [Block]; 3]),
    Points(&'a mut [[Point; LANES]]),
}

/// Sign bit of an incidence entry: the vertex is the spring's `b` end, so the force is negated.
pub const B_END: u32 = 0x8000_0000;

/// Edge-centric accumulation table: per entry, a spring slot with [`B_END`] for the far end.
/// Padding entries point at a slot whose force is always zero.
#[derive(Clone, Debug)]
pub struct IncidenceTable {
    pub slices: Slices,
    pub entry: IndexRows,
    /// Per slice, how many of its last rows are whole rows of the force pass, in order, each
    /// lane's spring in its own lane and owned by it (no [`B_END`]): the summing from points
    /// loads such a row with 4 vector loads instead of 8 point loads, inserts and signs.
    pub tails: Vec<u8>,
    /// Whether the spring slots hold stretches, each force `k d` then added as gather adds
    /// it; see [`SpringTable::stretches`].
    pub stretches: bool,
}

impl IncidenceTable {
    /// Whether scatter keeps its spring slots as points (and its force pass reads the
    /// positions as points): when most incidence rows load lane by lane, and always for
    /// stretches, whose `k` takes a point's fourth word.
    pub fn forces_as_points(&self) -> bool {
        self.entry.mostly_gathered() || self.stretches
    }
}

/// Per-vertex integration constants (see the module docs).
#[derive(Clone, Debug)]
pub struct Integrator {
    /// Per vertex: `dt^2 / m` (axis 0) and `1 - c dt / m` (axis 1).
    pub scales: Lanes<2>,
    /// `g dt^2`, m.
    pub gravity_step: [f32; 3],
}

/// Which implementation of [`Simd`] the kernels use.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub enum InstructionSet {
    /// AVX2 where the CPU has it, else portable.
    #[default]
    Best,
    /// Plain loops (for checking the vector path against them).
    Portable,
}

impl InstructionSet {
    /// The implementation actually used on this CPU.
    pub fn resolved_name(self) -> &'static str {
        #[cfg(target_arch = "x86_64")]
        if self == Self::Best
            && let Some(avx2) = Avx2::detect()
        {
            return if avx2.gathers_by_lane() {
                "avx2, gathers by lane"
            } else {
                "avx2"
            };
        }
        "portable"
    }
}

/// Defines a kernel that runs `generic` with AVX2 when available and allowed.
macro_rules! dispatch {
    ($(#[$doc:meta])* $vis:vis fn $name:ident($($arg:ident: $ty:ty),* $(,)?) -> $ret:ty => $generic:ident) => {
        $(#[$doc])*
        $vis fn $name(isa: InstructionSet, $($arg: $ty),*) -> $ret {
            #[cfg(target_arch = "x86_64")]
            if let (InstructionSet::Best, Some(avx2)) = (isa, Avx2::detect()) {
                #[target_feature(enable = "avx2,bmi1,fma")]
                fn with_avx2(simd: Avx2, $($arg: $ty),*) -> $ret {
                    $generic(simd, $($arg),*)
                }
                // SAFETY: `Avx2::detect` found AVX2, BMI1 and FMA on this CPU.
                return unsafe { with_avx2(avx2, $($arg),*) };
            }
            let _ = isa;
            #[cfg(target_arch = "x86_64")]
            if crate::simd::has_fma() {
                #[target_feature(enable = "fma")]
                fn portable_fused($($arg: $ty),*) -> $ret {
                    $generic(Portable::<true>, $($arg),*)
                }
                // SAFETY: `has_fma` found FMA on this CPU.
                return unsafe { portable_fused($($arg),*) };
            }
            #[cfg(target_arch = "x86_64")]
            return $generic(Portable::<false>, $($arg),*);
            #[cfg(not(target_arch = "x86_64"))]
            return $generic(Portable::<{ crate::simd::FUSED_ALWAYS }>, $($arg),*);
        }
    };
}

/// `values[entry & mask]` for the 8 entries of `row`; with `signed`, negated in lanes whose
/// entry has the [`B_END`] bit.
#[inline(always)]
fn load_row<S: Simd>(
    simd: S,
    values: Floats<'_>,
    rows: &IndexRows,
    row: usize,
    mask: u32,
    signed: bool,
) -> S::V {
    let head = rows.head[row];
    if rows.contiguous[row] {
        let value = simd.load(values.run((head & mask) as usize));
        if signed {
            simd.flip_sign(value, &[head; LANES])
        } else {
            value
        }
    } else {
        let index = &rows.gathered[head as usize];
        // SAFETY: `CpuSolver::new` builds every index (masked) below `values.len()`: vertex
        // indices below `padded_len`, spring slots below the force buffer's length.
        let value = unsafe { values.gather(simd, index, mask) };
        if signed {
            simd.flip_sign(value, index)
        } else {
            value
        }
    }
}

/// The positions of the 8 vertices of `row`: a contiguous row loads from the axes; another,
/// with `POINTS`, from the points (one 16-byte load per lane), else lane by lane from each
/// axis. (`POINTS` is a constant so that the structured meshes' loop never looks at points.)
#[inline(always)]
fn load_positions_row<S: Simd, const POINTS: bool>(
    simd: S,
    positions: Positions<'_>,
    rows: &IndexRows,
    row: usize,
) -> [S::V; 3] {
    match (positions.points, rows.point_offsets()) {
        (Some(points), Some(offsets)) if POINTS => {
            // SAFETY: `CpuSolver::new` builds every vertex index below `padded_len`, the length
            // of the points, and `IndexRows::new` made their offsets from them.
            unsafe { points.gather_points_at(simd, &offsets[row], u32::MAX) }
        }
        (Some(points), None) if POINTS && !rows.contiguous[row] => {
            let index = &rows.gathered[rows.head[row] as usize];
            // SAFETY: `CpuSolver::new` builds every vertex index below `padded_len`, the length
            // of the points.
            unsafe { points.gather_points(simd, index, u32::MAX) }
        }
        // Written out per axis: closures would not inline into the AVX2 functions.
        _ => {
            let [xs, ys, zs] = positions.axes;
            [
                load_row(simd, xs, rows, row, u32::MAX, false),
                load_row(simd, ys, rows, row, u32::MAX, false),
                load_row(simd, zs, rows, row, u32::MAX, false),
            ]
        }
    }
}

/// Force of 8 springs on their near ends: `(D - D l0/|d|) d` per axis, `d = x_far - x_near`.
#[inline(always)]
fn spring_force_rows<S: Simd>(
    simd: S,
    near: [S::V; 3],
    far: [S::V; 3],
    stiffness: S::V,
    rest: S::V,
) -> [S::V; 3] {
    let (k, [dx, dy, dz]) = spring_stretch_rows(simd, near, far, stiffness, rest);
    [simd.mul(k, dx), simd.mul(k, dy), simd.mul(k, dz)]
}

/// The stretch of 8 springs seen from their near ends: `k = D - D l0/|d|` and `d = x_far -
/// x_near`, whose product is the force ([`spring_force_rows`]).
#[inline(always)]
fn spring_stretch_rows<S: Simd>(
    simd: S,
    near: [S::V; 3],
    far: [S::V; 3],
    stiffness: S::V,
    rest: S::V,
) -> (S::V, [S::V; 3]) {
    // Written out per axis: closures (`[T; 3]::map`) would not inline into the AVX2 functions.
    let (dx, dy, dz) = (
        simd.sub(far[0], near[0]),
        simd.sub(far[1], near[1]),
        simd.sub(far[2], near[2]),
    );
    // Fused multiply-adds: on an irregular mesh, whose rows' loads and transposes keep the
    // floating-point ports busy, each operation fewer counts (see the performance log,
    // 2026-12-06: the gather step 8-11% faster with the integration's).
    // The smallest normal float added to the first square keeps a spring of length 0
    // (padding, or two vertices in one place) at a positive length: 0 force, not 0/0, where
    // a clamp would take one more operation. It changes no other length: it is below half
    // the spacing of floats near any square but the tiniest, and only tips a rounding tie.
    let tiny = simd.splat(f32::MIN_POSITIVE);
    let length_squared = simd.mul_add(dz, dz, simd.mul_add(dy, dy, simd.mul_add(dx, dx, tiny)));
    let length = simd.sqrt(length_squared);
    let k = simd.neg_mul_add(stiffness, simd.div(rest, length), stiffness);
    (k, [dx, dy, dz])
}

/// `force + k d`, each axis rounded once: an irregular mesh's spring forces summed (see
/// `gather_slice`).
#[inline(always)]
fn add_stretch<S: Simd>(simd: S, force: [S::V; 3], (k, d): (S::V, [S::V; 3])) -> [S::V; 3] {
    [
        simd.mul_add(k, d[0], force[0]),
        simd.mul_add(k, d[1], force[1]),
        simd.mul_add(k, d[2], force[2]),
    ]
}

/// The spring forces on slice `slice`, whose positions are `own`.
#[inline(always)]
fn gather_slice<S: Simd, const POINTS: bool>(
    simd: S,
    table: &GatherTable,
    positions: Positions<'_>,
    slice: usize,
    own: [S::V; 3],
) -> [S::V; 3] {
    let mut force = [simd.splat(0.0); 3];
    let rows = table.slices.rows(slice);
    if POINTS
        && let (Some(points), Some(offsets)) = (positions.points, table.neighbor.point_offsets())
    {
        // An irregular mesh's rows, read in order: zipped, without bounds checks per row.
        // Each force is added with fused multiply-adds, `k d` never rounded on its own: three
        // operations a row fewer, where the rows' transposes keep the floating-point ports
        // busy (the step 6-9% faster; see the performance log, 2026-12-06). Scatter sums
        // alike by storing stretches instead of forces (`tables::sums_fused`), which costs
        // it a shuffle and a product per point pair; on a grid, whose forces scatter keeps
        // as three axes (a fourth would cost memory), both methods add `k d` rounded, where
        // fusing saved the grid's gather only 2% when tried.
        let offsets = &offsets[rows.clone()];
        if let (Some(rest), Some(stiffness)) = (
            table.rest_length.whole_rows(),
            table.stiffness.uniform_row(),
        ) {
            let stiffness = simd.load(stiffness);
            for (offsets, rest) in offsets.iter().zip(&rest[rows]) {
                // SAFETY: as in `load_positions_row`.
                let neighbor = unsafe { points.gather_points_at(simd, offsets, u32::MAX) };
                let stretch = spring_stretch_rows(simd, own, neighbor, stiffness, simd.load(rest));
                force = add_stretch(simd, force, stretch);
            }
        } else {
            for (row, offsets) in rows.zip(offsets) {
                // SAFETY: as in `load_positions_row`.
                let neighbor = unsafe { points.gather_points_at(simd, offsets, u32::MAX) };
                let stiffness = simd.load(table.stiffness.row(row));
                let rest = table.rest_length.load(simd, row);
                let stretch = spring_stretch_rows(simd, own, neighbor, stiffness, rest);
                force = add_stretch(simd, force, stretch);
            }
        }
        return force;
    }
    for row in rows {
        let neighbor = load_positions_row::<S, POINTS>(simd, positions, &table.neighbor, row);
        let stiffness = simd.load(table.stiffness.row(row));
        let f = spring_force_rows(
            simd,
            own,
            neighbor,
            stiffness,
            table.rest_length.load(simd, row),
        );
        force = add3(simd, force, f);
    }
    force
}

/// `a + b`, axis by axis.
#[inline(always)]
fn add3<S: Simd>(simd: S, a: [S::V; 3], b: [S::V; 3]) -> [S::V; 3] {
    [
        simd.add(a[0], b[0]),
        simd.add(a[1], b[1]),
        simd.add(a[2], b[2]),
    ]
}

/// Sums the incident spring forces of `slice`'s vertices from three axes. Flipping the sign
/// bit negates exactly: the force on the spring's far end.
#[inline(always)]
fn accumulate_slice<S: Simd>(
    simd: S,
    table: &IncidenceTable,
    [xs, ys, zs]: [Floats<'_>; 3],
    slice: usize,
) -> [S::V; 3] {
    let mut force = [simd.splat(0.0); 3];
    for row in table.slices.rows(slice) {
        let fx = load_row(simd, xs, &table.entry, row, !B_END, true);
        let fy = load_row(simd, ys, &table.entry, row, !B_END, true);
        let fz = load_row(simd, zs, &table.entry, row, !B_END, true);
        force = add3(simd, force, [fx, fy, fz]);
    }
    force
}

/// How a spring slot's point adds into a pair of sums: forces as they are, or stretches.
/// Named types with inlined methods, as for [`SliceForces`].
trait SlotPoints {
    /// `sum + sign * point` for a pair of points, `sign` +1 or -1 per word.
    fn signed<S: Simd>(simd: S, sum: S::V, pair: S::V, sign: S::V) -> S::V;
    /// `sum + point` for a pair of points the lanes own (a sign of +1).
    fn owned<S: Simd>(simd: S, sum: S::V, pair: S::V) -> S::V;
}

/// Spring forces: signs applied by an exact fused multiply-add.
struct ForcePoints;

impl SlotPoints for ForcePoints {
    #[inline(always)]
    fn signed<S: Simd>(simd: S, sum: S::V, pair: S::V, sign: S::V) -> S::V {
        simd.add_signed(sum, pair, sign)
    }
    #[inline(always)]
    fn owned<S: Simd>(simd: S, sum: S::V, pair: S::V) -> S::V {
        simd.add(sum, pair)
    }
}

/// Stretches `(d, k)`: each force `k d` added as gather adds it, `sum + k d` rounded once (a
/// far end's `k` negated first, exactly). The fourth words sum `k^2` terms that nothing reads.
struct StretchPoints;

impl SlotPoints for StretchPoints {
    #[inline(always)]
    fn signed<S: Simd>(simd: S, sum: S::V, pair: S::V, sign: S::V) -> S::V {
        simd.mul_add(simd.mul(simd.fourths(pair), sign), pair, sum)
    }
    #[inline(always)]
    fn owned<S: Simd>(simd: S, sum: S::V, pair: S::V) -> S::V {
        simd.mul_add(simd.fourths(pair), pair, sum)
    }
}

/// [`accumulate_slice`] from one point per spring slot, forces or stretches as the table
/// says: each row's 8 points added as loaded, two to a value, their signs applied exactly,
/// and the sums transposed once per slice instead of once per row. The same additions in the
/// same order.
#[inline(always)]
fn accumulate_points_slice<S: Simd>(
    simd: S,
    table: &IncidenceTable,
    points: Points<'_>,
    slice: usize,
) -> [S::V; 3] {
    if table.stretches {
        sum_slot_points::<S, StretchPoints>(simd, table, points, slice)
    } else {
        sum_slot_points::<S, ForcePoints>(simd, table, points, slice)
    }
}

#[inline(always)]
fn sum_slot_points<S: Simd, P: SlotPoints>(
    simd: S,
    table: &IncidenceTable,
    points: Points<'_>,
    slice: usize,
) -> [S::V; 3] {
    let mut sum = [simd.splat(0.0); 4];
    let add = |sum: [S::V; 4], f: [S::V; 4], sign: [S::V; 4]| {
        [
            P::signed(simd, sum[0], f[0], sign[0]),
            P::signed(simd, sum[1], f[1], sign[1]),
            P::signed(simd, sum[2], f[2], sign[2]),
            P::signed(simd, sum[3], f[3], sign[3]),
        ]
    };
    let rows = table.slices.rows(slice);
    if let Some(offsets) = table.entry.point_offsets() {
        let tail = usize::from(table.tails[slice]);
        let (gathered, whole) = offsets[rows.clone()].split_at(rows.len() - tail);
        for offsets in gathered {
            // SAFETY: `IndexRows::new` made the offsets from spring slots below the force
            // buffer's length (the springs' rows and one row of zeros for padding).
            let f = unsafe { points.point_pairs_at(simd, offsets, !B_END) };
            sum = add(sum, f, simd.pair_signs(offsets));
        }
        for offsets in whole {
            // SAFETY: a tail's row is a whole row of spring slots in order, owned by its lanes
            // (`IncidenceTable::tails`), so its first offset starts 8 points in bounds.
            let f = unsafe { points.point_pairs_run(simd, offsets[0]) };
            sum = [
                P::owned(simd, sum[0], f[0]),
                P::owned(simd, sum[1], f[1]),
                P::owned(simd, sum[2], f[2]),
                P::owned(simd, sum[3], f[3]),
            ];
        }
        return simd.transpose_point_pairs(sum);
    }
    for row in rows {
        let index = table.entry.row(row);
        // Offsets without the flag, which they could reach on a mesh this large.
        let offsets = index.map(|e| point_offset(e, !B_END));
        // SAFETY: as above, for slots this table holds.
        let f = unsafe { points.point_pairs_at(simd, &offsets, u32::MAX) };
        sum = add(sum, f, simd.pair_signs(&index));
    }
    simd.transpose_point_pairs(sum)
}

#[inline(always)]
fn add_extra<S: Simd>(simd: S, force: [S::V; 3], extra: Option<&Soa>, slice: usize) -> [S::V; 3] {
    match extra {
        Some(extra) => {
            let [x, y, z] = extra.axes();
            add3(
                simd,
                force,
                [
                    simd.load(&x[slice]),
                    simd.load(&y[slice]),
                    simd.load(&z[slice]),
                ],
            )
        }
        None => force,
    }
}

/// One slice's outputs: the next positions and the position deltas.
struct SliceOut<'a> {
    next: [&'a mut Block; 3],
    delta: [&'a mut Block; 3],
}

/// Integrates one slice at `own`: writes `x(t+dt)` to `out.next` (unless `!axes`) and to
/// `points` if given, and updates `out.delta` in place. Returns a probe that is NaN in lanes
/// whose new position is not finite.
#[allow(clippy::too_many_arguments)] // one slice's inputs and outputs, inlined
#[inline(always)]
fn integrate_slice<S: Simd>(
    simd: S,
    integrator: &Integrator,
    slice: usize,
    own: [S::V; 3],
    force: [S::V; 3],
    out: SliceOut<'_>,
    axes: bool,
    points: Option<&mut [Point; LANES]>,
) -> S::V {
    let force_scale = simd.load(&integrator.scales.axis(0)[slice]);
    let velocity_scale = simd.load(&integrator.scales.axis(1)[slice]);
    let zero = simd.splat(0.0);
    let mut probe = zero;
    let mut news = [zero; 3];
    let SliceOut { next, delta } = out;
    // Indexed, not zipped: the compiler unrolls a counted loop over three axes, where the
    // arrays' by-value iterators kept their state on the stack.
    for axis in 0..3 {
        let (next, delta) = (&mut *next[axis], &mut *delta[axis]);
        let x = own[axis];
        let moved = simd.add(
            simd.mul_add(
                force[axis],
                force_scale,
                simd.mul(simd.load(delta), velocity_scale),
            ),
            simd.splat(integrator.gravity_step[axis]),
        );
        // Select rather than scale by zero: a pinned vertex must stay put even if a force is inf.
        let new_delta = simd.select_positive(force_scale, moved, zero);
        let new = simd.select_positive(force_scale, simd.add(x, new_delta), x);
        simd.store(new_delta, delta);
        if axes {
            simd.store(new, next);
        }
        news[axis] = new;
        probe = simd.add(probe, simd.mul(new, zero));
    }
    if let Some(points) = points {
        simd.store_points(news, points);
    }
    probe
}

/// Iterates a chunk's outputs slice by slice.
fn slice_outputs<'a>(
    first: usize,
    [nx, ny, nz]: [&'a mut [Block]; 3],
    [dx, dy, dz]: [&'a mut [Block]; 3],
) -> impl Iterator<Item = (usize, SliceOut<'a>)> {
    nx.iter_mut()
        .zip(ny.iter_mut())
        .zip(nz.iter_mut())
        .zip(dx.iter_mut().zip(dy.iter_mut()).zip(dz.iter_mut()))
        .enumerate()
        .map(move |(k, (((nx, ny), nz), ((dx, dy), dz)))| {
            (
                first + k,
                SliceOut {
                    next: [nx, ny, nz],
                    delta: [dx, dy, dz],
                },
            )
        })
}

fn is_finite_probe<S: Simd>(simd: S, probe: S::V) -> bool {
    let mut lanes = [0.0; LANES];
    simd.store(probe, &mut lanes);
    lanes.iter().all(|p| *p == 0.0)
}

/// A vertex-pass chunk: its first slice, where its next positions go (and, when the next
/// step's force pass reads them, the same as points) and its deltas.
#[derive(Debug)]
pub struct VertexChunk<'a> {
    pub first_slice: usize,
    pub next: [&'a mut [Block]; 3],
    /// Whether to write `next` (else only the points, which must then be given): a sweep's
    /// steps before its last, whose positions only the next step's force pass reads.
    pub axes: bool,
    pub delta: [&'a mut [Block]; 3],
    pub points: Option<&'a mut [[Point; LANES]]>,
}

/// A chunk of per-slice force output (phase-separated steps).
#[derive(Debug)]
pub struct ForceChunk<'a> {
    pub first_slice: usize,
    pub out: [&'a mut [Block]; 3],
}

/// Where a vertex pass takes each slice's net spring force from. Named types with an inlined
/// method rather than closures: a closure called from two loops would not inline into the AVX2
/// functions, and its intrinsics would become calls.
trait SliceForces {
    /// Whether [`SliceForces::of`] reads `own`; others get zeros, and the vertex pass loads a
    /// slice's positions after its force (fewer values held across the force's loop).
    const READS_OWN: bool = false;
    /// Slice `slice`'s positions as [`SliceForces::of`] reads them (zeros where it reads
    /// none), for a pass that has no positions of its own to hand it.
    #[inline(always)]
    fn own<S: Simd>(&self, simd: S, _slice: usize) -> [S::V; 3] {
        [simd.splat(0.0); 3]
    }
    /// The net spring force on slice `slice`, whose positions are `own`.
    fn of<S: Simd>(&self, simd: S, slice: usize, own: [S::V; 3]) -> [S::V; 3];
}

/// Gather: each slice sums its springs; with `POINTS`, gathered rows read the points.
struct Gathered<'a, const POINTS: bool> {
    table: &'a GatherTable,
    current: Positions<'a>,
}

impl<const POINTS: bool> SliceForces for Gathered<'_, POINTS> {
    const READS_OWN: bool = true;
    #[inline(always)]
    fn own<S: Simd>(&self, simd: S, slice: usize) -> [S::V; 3] {
        own_positions::<S, false>(simd, self.current, slice)
    }
    #[inline(always)]
    fn of<S: Simd>(&self, simd: S, slice: usize, own: [S::V; 3]) -> [S::V; 3] {
        gather_slice::<S, POINTS>(simd, self.table, self.current, slice, own)
    }
}

/// Scatter: each slice sums its springs' forces from the force pass, kept in three axes.
struct Accumulated<'a> {
    table: &'a IncidenceTable,
    spring_forces: [Floats<'a>; 3],
}

impl SliceForces for Accumulated<'_> {
    #[inline(always)]
    fn of<S: Simd>(&self, simd: S, slice: usize, _: [S::V; 3]) -> [S::V; 3] {
        accumulate_slice(simd, self.table, self.spring_forces, slice)
    }
}

/// [`Accumulated`] from one point per spring slot.
struct AccumulatedPoints<'a> {
    table: &'a IncidenceTable,
    spring_forces: Points<'a>,
}

impl SliceForces for AccumulatedPoints<'_> {
    #[inline(always)]
    fn of<S: Simd>(&self, simd: S, slice: usize, _: [S::V; 3]) -> [S::V; 3] {
        accumulate_points_slice(simd, self.table, self.spring_forces, slice)
    }
}

/// Net forces already summed per vertex (the phase-separated step).
struct Summed<'a>(&'a Soa);

impl SliceForces for Summed<'_> {
    #[inline(always)]
    fn of<S: Simd>(&self, simd: S, slice: usize, _: [S::V; 3]) -> [S::V; 3] {
        let [fx, fy, fz] = self.0.axes();
        [
            simd.load(&fx[slice]),
            simd.load(&fy[slice]),
            simd.load(&fz[slice]),
        ]
    }
}

/// The positions of slice `slice`: from `current`'s points with `POINTS` where it has them,
/// else from its axes.
#[inline(always)]
fn own_positions<S: Simd, const POINTS: bool>(
    simd: S,
    current: Positions<'_>,
    slice: usize,
) -> [S::V; 3] {
    match current.points {
        Some(points) if POINTS => simd.load_points(points.slice(slice)),
        _ => [
            simd.load(current.block(0, slice)),
            simd.load(current.block(1, slice)),
            simd.load(current.block(2, slice)),
        ],
    }
}

/// A slice's positions (see [`own_positions`]) and net spring force, in the order that
/// `forces` needs them.
#[inline(always)]
fn own_and_force<S: Simd, const POINTS: bool, F: SliceForces>(
    simd: S,
    current: Positions<'_>,
    slice: usize,
    forces: &F,
) -> ([S::V; 3], [S::V; 3]) {
    if F::READS_OWN {
        let own = own_positions::<S, POINTS>(simd, current, slice);
        (own, forces.of(simd, slice, own))
    } else {
        let force = forces.of(simd, slice, [simd.splat(0.0); 3]);
        (own_positions::<S, POINTS>(simd, current, slice), force)
    }
}

/// The vertex pass every step ends with: each slice's net force (from `forces`, plus the
/// extra forces), then Verlet, each slice's positions read from `current`'s points with
/// `OWN_POINTS`, else from its axes. False if a new position in the chunk is not finite.
#[inline(always)]
fn integrate_chunk<S: Simd, const OWN_POINTS: bool>(
    simd: S,
    integrator: &Integrator,
    current: Positions<'_>,
    extra: Option<&Soa>,
    chunk: VertexChunk<'_>,
    forces: &impl SliceForces,
) -> bool {
    let mut probe = simd.splat(0.0);
    let axes = chunk.axes;
    let outputs = slice_outputs(chunk.first_slice, chunk.next, chunk.delta);
    // Two copies of the loop, one that writes no points: the structured meshes' steps.
    match chunk.points {
        None => {
            assert!(axes, "a vertex pass writes its positions somewhere");
            for (slice, out) in outputs {
                let (own, force) = own_and_force::<S, OWN_POINTS, _>(simd, current, slice, forces);
                let force = add_extra(simd, force, extra, slice);
                let p = integrate_slice(simd, integrator, slice, own, force, out, true, None);
                probe = simd.add(probe, p);
            }
        }
        Some(points) => {
            for ((slice, out), points) in outputs.zip(points) {
                let (own, force) = own_and_force::<S, OWN_POINTS, _>(simd, current, slice, forces);
                let force = add_extra(simd, force, extra, slice);
                let p =
                    integrate_slice(simd, integrator, slice, own, force, out, axes, Some(points));
                probe = simd.add(probe, p);
            }
        }
    }
    is_finite_probe(simd, probe)
}

#[inline(always)]
fn gather_and_integrate_with<S: Simd>(
    simd: S,
    table: &GatherTable,
    integrator: &Integrator,
    current: Positions<'_>,
    extra: Option<&Soa>,
    chunk: VertexChunk<'_>,
) -> bool {
    // Two copies of the loop, one that never looks at points: the structured meshes' rows.
    if current.points.is_some() {
        let forces = Gathered::<true> { table, current };
        integrate_chunk::<S, true>(simd, integrator, current, extra, chunk, &forces)
    } else {
        let forces = Gathered::<false> { table, current };
        integrate_chunk::<S, false>(simd, integrator, current, extra, chunk, &forces)
    }
}

dispatch! {
    /// Gather (PCA), fused: spring forces of each slice's vertices, then Verlet, in one pass.
    /// Gathered rows read `current`'s points when it has them. Returns false if a new
    /// position in the chunk is not finite.
    pub fn gather_and_integrate(
        table: &GatherTable,
        integrator: &Integrator,
        current: Positions<'_>,
        extra: Option<&Soa>,
        chunk: VertexChunk<'_>,
    ) -> bool => gather_and_integrate_with
}

/// Integrates a chunk from the forces `forces` sums.
#[inline(always)]
fn integrate_summed<S: Simd, F: SliceForces>(
    simd: S,
    forces: F,
    integrator: &Integrator,
    current: Positions<'_>,
    extra: Option<&Soa>,
    chunk: VertexChunk<'_>,
) -> bool {
    integrate_chunk::<S, false>(simd, integrator, current, extra, chunk, &forces)
}

dispatch! {
    /// [`accumulate_and_integrate`] for one way of summing: a kernel of its own for each.
    fn sum_and_integrate(
        forces: impl SliceForces,
        integrator: &Integrator,
        current: Positions<'_>,
        extra: Option<&Soa>,
        chunk: VertexChunk<'_>,
    ) -> bool => integrate_summed
}

/// Scatter (ECA) accumulation by incidence, fused with Verlet: each vertex sums the
/// precomputed forces of its springs in a fixed order (deterministic for any thread count),
/// then integrates.
pub fn accumulate_and_integrate(
    isa: InstructionSet,
    table: &IncidenceTable,
    spring_forces: ForcesView<'_>,
    integrator: &Integrator,
    current: Positions<'_>,
    extra: Option<&Soa>,
    chunk: VertexChunk<'_>,
) -> bool {
    // A kernel for each layout of the forces (`sum_and_integrate` is compiled once per type):
    // compiled as one function, the points' loop (its tails) cost the axes' loop a base
    // address reloaded from the stack every row, and a grid's scatter step 2-3% (see the
    // performance log).
    match spring_forces {
        ForcesView::Axes(spring_forces) => {
            let forces = Accumulated {
                table,
                spring_forces,
            };
            sum_and_integrate(isa, forces, integrator, current, extra, chunk)
        }
        ForcesView::Points(spring_forces) => {
            let forces = AccumulatedPoints {
                table,
                spring_forces,
            };
            sum_and_integrate(isa, forces, integrator, current, extra, chunk)
        }
    }
}

/// A spring row's `a` ends, `b` ends, stiffness and rest length.
type RowInputs<V> = ([V; 3], [V; 3], V, V);

/// Row `row`'s ends, stiffness and rest length.
#[inline(always)]
fn spring_row_inputs<S: Simd, const POINTS: bool>(
    simd: S,
    springs: &SpringTable,
    positions: Positions<'_>,
    row: usize,
) -> RowInputs<S::V> {
    (
        load_positions_row::<S, POINTS>(simd, positions, &springs.a, row),
        load_positions_row::<S, POINTS>(simd, positions, &springs.b, row),
        simd.load(springs.stiffness.row(row)),
        springs.rest_length.load(simd, row),
    )
}

/// Both ends of an irregular mesh's spring row: a run of first ends (a slice's vertices,
/// `owned_rows`) with three vector loads from the axes, others and the far ends point by
/// point.
///
/// # Safety
/// A run must start at least 8 floats before the end of the axes, and every offset must be
/// that of a point in bounds (see [`Simd::gather_points_at`]).
#[inline(always)]
unsafe fn irregular_row_ends<S: Simd>(
    simd: S,
    [xs, ys, zs]: [Floats<'_>; 3],
    points: Points<'_>,
    ((a, b), run): ((&[u32; LANES], &[u32; LANES]), Option<u32>),
) -> ([S::V; 3], [S::V; 3]) {
    // SAFETY: the caller's guarantee.
    unsafe {
        let a = match run {
            Some(first) => {
                let first = first as usize;
                [
                    simd.load(xs.run_unchecked(first)),
                    simd.load(ys.run_unchecked(first)),
                    simd.load(zs.run_unchecked(first)),
                ]
            }
            None => points.gather_points_at(simd, a, u32::MAX),
        };
        (a, points.gather_points_at(simd, b, u32::MAX))
    }
}

#[inline(always)]
fn spring_forces_with<S: Simd>(
    simd: S,
    springs: &SpringTable,
    positions: Positions<'_>,
    first_row: usize,
    out: ForceRows<'_>,
) {
    // Two copies of the loop, one that never looks at points: the structured meshes' rows.
    match positions.points {
        None => spring_rows::<S, false>(simd, springs, positions, first_row, out),
        Some(_) => spring_rows::<S, true>(simd, springs, positions, first_row, out),
    }
}

#[inline(always)]
fn spring_rows<S: Simd, const POINTS: bool>(
    simd: S,
    springs: &SpringTable,
    positions: Positions<'_>,
    first_row: usize,
    out: ForceRows<'_>,
) {
    // Calls, not a closure: closures would not inline into the AVX2 functions.
    match out {
        ForceRows::Axes([ox, oy, oz]) => {
            debug_assert!(!springs.stretches, "stretches are stored as points");
            for (k, ((fx, fy), fz)) in ox
                .iter_mut()
                .zip(oy.iter_mut())
                .zip(oz.iter_mut())
                .enumerate()
            {
                let (a, b, stiffness, rest) =
                    spring_row_inputs::<S, POINTS>(simd, springs, positions, first_row + k);
                let [f0, f1, f2] = spring_force_rows(simd, a, b, stiffness, rest);
                simd.store(f0, fx);
                simd.store(f1, fy);
                simd.store(f2, fz);
            }
        }
        ForceRows::Points(rows) => {
            if POINTS
                && let (Some(points), Some(a), Some(b)) = (
                    positions.points,
                    springs.a.point_offsets(),
                    springs.b.point_offsets(),
                )
            {
                // An irregular mesh's rows, read in order: zipped, without bounds checks.
                let range = first_row..first_row + rows.len();
                let runs = springs.a.runs(range.clone());
                let ends = a[range.clone()].iter().zip(&b[range.clone()]).zip(runs);
                if let (Some(rest), Some(stiffness)) = (
                    springs.rest_length.whole_rows(),
                    springs.stiffness.uniform_row(),
                ) {
                    let stiffness = simd.load(stiffness);
                    let rest = &rest[range];
                    for ((ends, rest), out) in ends.zip(rest).zip(rows) {
                        // SAFETY: `IndexRows::new` built the runs and offsets of both ends
                        // from vertex indices below `padded_len`, the length of the axes
                        // and the points.
                        let (a, b) =
                            unsafe { irregular_row_ends(simd, positions.axes, points, ends) };
                        let rest = simd.load(rest);
                        store_spring_row(simd, springs.stretches, a, b, stiffness, rest, out);
                    }
                    return;
                }
                for ((row, ends), out) in range.zip(ends).zip(rows) {
                    // SAFETY: as above.
                    let (a, b) = unsafe { irregular_row_ends(simd, positions.axes, points, ends) };
                    let stiffness = simd.load(springs.stiffness.row(row));
                    let rest = springs.rest_length.load(simd, row);
                    store_spring_row(simd, springs.stretches, a, b, stiffness, rest, out);
                }
                return;
            }
            for (k, out) in rows.iter_mut().enumerate() {
                let (a, b, stiffness, rest) =
                    spring_row_inputs::<S, POINTS>(simd, springs, positions, first_row + k);
                store_spring_row(simd, springs.stretches, a, b, stiffness, rest, out);
            }
        }
    }
}

/// Stores a row of springs as points: their stretches, or their forces.
#[inline(always)]
fn store_spring_row<S: Simd>(
    simd: S,
    stretches: bool,
    a: [S::V; 3],
    b: [S::V; 3],
    stiffness: S::V,
    rest: S::V,
    out: &mut [Point; LANES],
) {
    if stretches {
        let (k, d) = spring_stretch_rows(simd, a, b, stiffness, rest);
        simd.store_stretches(d, k, out);
    } else {
        simd.store_points(spring_force_rows(simd, a, b, stiffness, rest), out);
    }
}

dispatch! {
    /// Scatter (ECA) force pass: each spring's force on its `a` end, computed once, for rows
    /// `first_row..first_row + out.len()`. Rows gathered lane by lane read the positions'
    /// points (one per vertex) when they have them.
    pub fn spring_forces(
        springs: &SpringTable,
        positions: Positions<'_>,
        first_row: usize,
        out: ForceRows<'_>,
    ) -> () => spring_forces_with
}

/// Stores each slice's net spring force.
#[inline(always)]
fn store_forces<S: Simd>(simd: S, chunk: ForceChunk<'_>, forces: &impl SliceForces) {
    let [ox, oy, oz] = chunk.out;
    for (k, ((bx, by), bz)) in ox
        .iter_mut()
        .zip(oy.iter_mut())
        .zip(oz.iter_mut())
        .enumerate()
    {
        let slice = chunk.first_slice + k;
        let [fx, fy, fz] = forces.of(simd, slice, forces.own(simd, slice));
        simd.store(fx, bx);
        simd.store(fy, by);
        simd.store(fz, bz);
    }
}

#[inline(always)]
fn gather_forces_with<S: Simd>(
    simd: S,
    table: &GatherTable,
    current: &Soa,
    points: Option<&[Point]>,
    chunk: ForceChunk<'_>,
) {
    let current = Positions::new(current, points);
    match points {
        None => store_forces(simd, chunk, &Gathered::<false> { table, current }),
        Some(_) => store_forces(simd, chunk, &Gathered::<true> { table, current }),
    }
}

dispatch! {
    /// Phase-separated gather (for per-phase timing): net spring force per vertex.
    pub fn gather_forces(
        table: &GatherTable,
        current: &Soa,
        points: Option<&[Point]>,
        chunk: ForceChunk<'_>,
    ) -> () => gather_forces_with
}

#[inline(always)]
fn accumulate_forces_with<S: Simd>(
    simd: S,
    table: &IncidenceTable,
    spring_forces: ForcesView<'_>,
    chunk: ForceChunk<'_>,
) {
    match spring_forces {
        ForcesView::Axes(spring_forces) => {
            let forces = Accumulated {
                table,
                spring_forces,
            };
            store_forces(simd, chunk, &forces);
        }
        ForcesView::Points(spring_forces) => {
            let forces = AccumulatedPoints {
                table,
                spring_forces,
            };
            store_forces(simd, chunk, &forces);
        }
    }
}

dispatch! {
    /// Phase-separated scatter accumulation (for per-phase timing): net force per vertex.
    pub fn accumulate_forces(table: &IncidenceTable, spring_forces: ForcesView<'_>, chunk: ForceChunk<'_>) -> ()
        => accumulate_forces_with
}

#[inline(always)]
fn integrate_with<S: Simd>(
    simd: S,
    integrator: &Integrator,
    current: &Soa,
    forces: &Soa,
    extra: Option<&Soa>,
    chunk: VertexChunk<'_>,
) -> bool {
    let current = Positions::new(current, None);
    integrate_chunk::<S, false>(simd, integrator, current, extra, chunk, &Summed(forces))
}

dispatch! {
    /// Phase-separated Verlet (for per-phase timing) from net per-vertex forces.
    pub fn integrate(
        integrator: &Integrator,
        current: &Soa,
        forces: &Soa,
        extra: Option<&Soa>,
        chunk: VertexChunk<'_>,
    ) -> bool => integrate_with
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::simd::point_slot;

    /// The summing from point offsets, with or without taking its tails' rows whole, and,
    /// where they would not fit (a mesh of some 2^27 spring slots), from the rows' entries:
    /// the same sums, bit for bit, with either instruction set, and those of flipping each
    /// far end's force and adding it.
    #[test]
    fn irregular_summing_gives_the_same_sums_from_offsets_or_entries() {
        let slots = 40 * LANES as u32;
        let entry = |slice: usize, row: usize, lane: usize| {
            let slot = ((slice * 7 + row * 13 + lane * 29) as u32 * 37) % slots;
            slot | if (slice + row + lane).is_multiple_of(3) {
                B_END
            } else {
                0
            }
        };
        let widths = [3usize, 5, 1, 6];
        // Slice 1's last two rows are force rows 10 and 11 whole, slice 3's last row 20.
        let tails = vec![0u8, 2, 0, 1];
        let whole_rows = [[0, 0], [10, 11], [0, 0], [20, 0]];
        let mut slice_rows = vec![0u32];
        let mut rows = Vec::new();
        for (slice, width) in widths.iter().enumerate() {
            for row in 0..*width {
                let tail = usize::from(tails[slice]);
                rows.push(match (row + tail).checked_sub(*width) {
                    Some(k) => {
                        std::array::from_fn(|lane| (whole_rows[slice][k] * LANES + lane) as u32)
                    }
                    None => std::array::from_fn(|lane| entry(slice, row, lane)),
                });
            }
            slice_rows.push(rows.len() as u32);
        }
        // Forces, or stretches whose fourth word is `k`.
        let forces: Vec<[Point; LANES]> = (0..40)
            .map(|r| {
                std::array::from_fn(|k| {
                    let v = (r * LANES + k) as f32;
                    [0.1 * v + 1e-3, -1.7 * v, 3.0e5 / (v + 1.0), 0.3 - 1e-3 * v]
                })
            })
            .collect();
        let view = ForcesView::Points(Points::new(forces.as_flattened()));
        for stretches in [false, true] {
            check_sums(
                &rows,
                &slice_rows,
                &widths,
                &tails,
                &forces,
                view,
                slots,
                stretches,
            );
        }
    }

    /// Sums `forces` (or stretches) by incidence rows `rows` stored every way, against a plain
    /// loop.
    #[allow(clippy::too_many_arguments)] // one table's parts
    fn check_sums(
        rows: &[[u32; LANES]],
        slice_rows: &[u32],
        widths: &[usize],
        tails: &Vec<u8>,
        forces: &[[Point; LANES]],
        view: ForcesView<'_>,
        slots: u32,
        stretches: bool,
    ) {
        let table = |form, tails: &Vec<u8>| IncidenceTable {
            slices: Slices {
                slice_rows: slice_rows.to_vec(),
            },
            entry: IndexRows::new(rows.to_vec(), !B_END, slots as usize, form),
            tails: tails.clone(),
            stretches,
        };
        let no_tails = vec![0; widths.len()];
        let (offsets, whole, entries) = (
            table(RowForm::Points, &no_tails),
            table(RowForm::Points, tails),
            table(RowForm::Runs, &no_tails),
        );
        assert!(offsets.entry.point_offsets().is_some() && entries.entry.point_offsets().is_none());
        let sums = |table: &IncidenceTable, isa| {
            let mut out = vec![[0.0; LANES]; 3 * widths.len()];
            let (x, rest) = out.split_at_mut(widths.len());
            let (y, z) = rest.split_at_mut(widths.len());
            let chunk = ForceChunk {
                first_slice: 0,
                out: [x, y, z],
            };
            accumulate_forces(isa, table, view, chunk);
            out
        };
        // Whether the portable kernels round a multiply-add once here (as `dispatch!` picks).
        #[cfg(target_arch = "x86_64")]
        let fused = crate::simd::has_fma();
        #[cfg(not(target_arch = "x86_64"))]
        let fused = crate::simd::FUSED_ALWAYS;
        let expected = sums(&offsets, InstructionSet::Portable);
        for isa in [InstructionSet::Best, InstructionSet::Portable] {
            for table in [&offsets, &whole, &entries] {
                let got = sums(table, isa);
                let bits =
                    |v: &Vec<Block>| v.iter().flatten().map(|f| f.to_bits()).collect::<Vec<_>>();
                assert_eq!(bits(&got), bits(&expected), "{isa:?}");
            }
        }
        for (slice, _) in widths.iter().enumerate() {
            for lane in 0..LANES {
                let mut sum = [0.0f32; 3];
                for row in offsets.slices.rows(slice) {
                    let e = rows[row][lane];
                    let slot = (e & !B_END) as usize;
                    let f = forces[slot / LANES][point_slot((slot % LANES) as u32) as usize];
                    let sign = if e & B_END != 0 { -1.0 } else { 1.0 };
                    for axis in 0..3 {
                        sum[axis] = match stretches {
                            // As gather adds a force: `k d` rounded once with the sum.
                            true if fused => (f[3] * sign).mul_add(f[axis], sum[axis]),
                            true => sum[axis] + f[3] * sign * f[axis],
                            false => sum[axis] + sign * f[axis],
                        };
                    }
                }
                for axis in 0..3 {
                    let got = expected[axis * widths.len() + slice][lane];
                    assert_eq!(
                        got.to_bits(),
                        sum[axis].to_bits(),
                        "slice {slice} lane {lane}, stretches {stretches}"
                    );
                }
            }
        }
    }

    #[test]
    fn value_rows_give_back_every_row_compacted_or_not() {
        let mut rows: Vec<Block> = (0..40).map(|r| [r as f32 * 0.5; LANES]).collect();
        rows[3][5] = 7.0;
        rows[17][0] = -0.0; // a different bit pattern from 0.0: the row is not uniform
        rows[16] = [0.0; LANES];
        let compact = ValueRows::new(rows.clone());
        assert!((compact.uniform_share() - 38.0 / 40.0).abs() < 1e-12);
        assert_eq!(compact.bytes(), 40 * 5 + 2 * 32);
        // Mostly non-uniform rows are stored whole.
        let mixed: Vec<Block> = (0..40)
            .map(|r| std::array::from_fn(|lane| (r * LANES + lane) as f32))
            .collect();
        let whole = ValueRows::new(mixed.clone());
        assert_eq!(whole.uniform_share(), 0.0);
        assert_eq!(whole.bytes(), 40 * 32);
        for (table, rows) in [(compact, rows), (whole, mixed)] {
            assert_eq!(table.len(), rows.len());
            for (r, expected) in rows.iter().enumerate() {
                let row = table.row(r);
                let loaded = table.load(Portable::<false>, r);
                for lane in 0..LANES {
                    assert_eq!(row[lane].to_bits(), expected[lane].to_bits(), "row {r}");
                    assert_eq!(loaded[lane].to_bits(), expected[lane].to_bits(), "row {r}");
                }
            }
        }
    }
}
