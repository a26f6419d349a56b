//! The per-chunk kernels of one time step, written as 8-lane loops that LLVM turns into SIMD.
//!
//! Each public kernel handles a contiguous chunk of slices (or spring rows) and is compiled for
//! several instruction sets by `multiversion`, picked at run time. No kernel uses fused
//! multiply-add or reassociates, so every instruction set gives bit-identical results.
//!
//! Spring force (paper eq. 1, sign of eq. 4) on vertex `i` from spring `ij`:
//! `D_ij (1 - |l0_ij| / |l_ij|) (x_j - x_i)`. Swapping `i` and `j` negates `x_j - x_i` exactly in
//! floating point and leaves the scale unchanged, so the force of a spring computed from either
//! end (gather) or once and negated (scatter) is the same number.
//!
//! Verlet with damping (eq. 3-4) in delta form. The state is `x` and `d = x - x_prev`; with
//! precomputed `a = dt^2 / m` and `v = 1 - c dt / m` (both 0 for pinned and padding vertices):
//! `d(t+dt) = v d + a F_springs + g dt^2`, `x(t+dt) = x + d(t+dt)`; pinned vertices keep `x`.
//! This is eq. 3 rearranged, but in float32 it matters: `x - x_prev` and `a F dt^2` are far
//! smaller than `x`, and storing `x_prev` rounds them to the ulp of `x` every step (a free fall
//! from 2 m at dt = 1e-4 s loses 21% of its distance that way). Stored as `d` they keep their
//! own precision, and only `x + d` rounds, without feeding back into the velocity.

use multiversion::multiversion;

use crate::layout::{LANES, Slices};

/// One lane-block (8 vertices or springs) of one scalar quantity.
pub type Block = [f32; LANES];

/// Three axes of per-vertex (or per-spring) vectors, in blocks of 8.
#[derive(Clone, Debug, Default)]
pub struct Soa {
    pub axes: [Vec<Block>; 3],
}

impl Soa {
    pub fn zeros(blocks: usize) -> Self {
        Self {
            axes: std::array::from_fn(|_| vec![[0.0; LANES]; blocks]),
        }
    }

    pub fn blocks(&self) -> usize {
        self.axes[0].len()
    }

    pub fn get(&self, index: usize) -> [f32; 3] {
        self.axes
            .each_ref()
            .map(|a| a[index / LANES][index % LANES])
    }

    pub fn set(&mut self, index: usize, value: [f32; 3]) {
        for (axis, v) in self.axes.iter_mut().zip(value) {
            axis[index / LANES][index % LANES] = v;
        }
    }

    pub fn bytes(&self) -> usize {
        3 * self.blocks() * std::mem::size_of::<Block>()
    }
}

/// Spring stiffness per entry, or one value for all (which saves a memory stream).
#[derive(Clone, Debug)]
pub enum Stiffness {
    Uniform(f32),
    PerEntry(Vec<Block>),
}

impl Stiffness {
    pub fn bytes(&self) -> usize {
        match self {
            Self::Uniform(_) => 0,
            Self::PerEntry(rows) => std::mem::size_of_val(rows.as_slice()),
        }
    }
}

/// Point-centric (PCA) table: for each entry, the neighbour and the spring's constants.
#[derive(Clone, Debug)]
pub struct GatherTable {
    pub slices: Slices,
    /// Per entry: internal index of the neighbour (the lane's own vertex for padding).
    pub neighbor: Vec<[u32; LANES]>,
    /// Per entry: rest length, m (0 for padding).
    pub rest_length: Vec<Block>,
    pub stiffness: Stiffness,
}

/// Edge-centric (ECA) springs, in rows of 8; the last row may hold zero-force padding springs.
#[derive(Clone, Debug)]
pub struct SpringTable {
    pub a: Vec<[u32; LANES]>,
    pub b: Vec<[u32; LANES]>,
    pub rest_length: Vec<Block>,
    pub stiffness: Stiffness,
}

/// Sign bit of an incidence entry: the vertex is the spring's `b` end, so the force is negated.
pub const B_END: u32 = 0x8000_0000;

/// Edge-centric accumulation table: per entry, a spring slot with [`B_END`] for the far end.
/// Padding entries point at a slot whose force is always zero.
#[derive(Clone, Debug)]
pub struct IncidenceTable {
    pub slices: Slices,
    pub entry: Vec<[u32; LANES]>,
}

/// Per-vertex integration constants (see the module docs).
#[derive(Clone, Debug)]
pub struct Integrator {
    pub force_scale: Vec<Block>,
    pub velocity_scale: Vec<Block>,
    /// `g dt^2`, m.
    pub gravity_step: [f32; 3],
}

#[inline(always)]
fn spring_scale(stiffness: f32, rest_length: f32, length_squared: f32) -> f32 {
    // Padding entries have length 0; the clamp keeps them at 0 force instead of 0/0.
    let length = length_squared.max(f32::MIN_POSITIVE).sqrt();
    stiffness * (1.0 - rest_length / length)
}

#[inline(always)]
fn stiffness_at(stiffness: &Stiffness, row: usize, lane: usize) -> f32 {
    match stiffness {
        Stiffness::Uniform(d) => *d,
        Stiffness::PerEntry(rows) => rows[row][lane],
    }
}

#[inline(always)]
fn gather_slice(table: &GatherTable, positions: &Soa, slice: usize) -> [Block; 3] {
    let [xs, ys, zs] = positions.axes.each_ref().map(|a| a.as_flattened());
    let [xi, yi, zi] = positions.axes.each_ref().map(|a| a[slice]);
    let mut force = [[0.0f32; LANES]; 3];
    for row in table.slices.rows(slice) {
        let neighbor = &table.neighbor[row];
        let rest = &table.rest_length[row];
        for lane in 0..LANES {
            let j = neighbor[lane] as usize;
            // SAFETY: `CpuSolver::new` builds every neighbour index from the numbering, so
            // `j < padded_len`, and every position axis has exactly `padded_len` values.
            let (xj, yj, zj) = unsafe {
                (
                    *xs.get_unchecked(j),
                    *ys.get_unchecked(j),
                    *zs.get_unchecked(j),
                )
            };
            let (dx, dy, dz) = (xj - xi[lane], yj - yi[lane], zj - zi[lane]);
            let k = spring_scale(
                stiffness_at(&table.stiffness, row, lane),
                rest[lane],
                dx * dx + dy * dy + dz * dz,
            );
            force[0][lane] += k * dx;
            force[1][lane] += k * dy;
            force[2][lane] += k * dz;
        }
    }
    force
}

#[inline(always)]
fn accumulate_slice(table: &IncidenceTable, spring_forces: &Soa, slice: usize) -> [Block; 3] {
    let axes = spring_forces.axes.each_ref().map(|a| a.as_flattened());
    let mut force = [[0.0f32; LANES]; 3];
    for row in table.slices.rows(slice) {
        let entry = &table.entry[row];
        for lane in 0..LANES {
            let slot = (entry[lane] & !B_END) as usize;
            let sign = entry[lane] & B_END;
            for axis in 0..3 {
                // SAFETY: `CpuSolver::new` builds every slot as a spring index or the zero slot,
                // all below the force buffer's length.
                let f = unsafe { *axes[axis].get_unchecked(slot) };
                force[axis][lane] += f32::from_bits(f.to_bits() ^ sign);
            }
        }
    }
    force
}

/// Integrates one slice: writes `x(t+dt)` to `out.next` and updates `out.delta` in place.
/// Returns a probe that is NaN if any new position is not finite.
#[inline(always)]
fn integrate_slice(
    integrator: &Integrator,
    current: &Soa,
    slice: usize,
    force: &[Block; 3],
    out: SliceOut<'_>,
) -> Block {
    let force_scale = &integrator.force_scale[slice];
    let velocity_scale = &integrator.velocity_scale[slice];
    let mut probe = [0.0f32; LANES];
    for (axis, (next, delta)) in out.next.into_iter().zip(out.delta).enumerate() {
        let x = &current.axes[axis][slice];
        let gravity = integrator.gravity_step[axis];
        for lane in 0..LANES {
            let moved = delta[lane] * velocity_scale[lane]
                + force[axis][lane] * force_scale[lane]
                + gravity;
            // Select rather than scale by zero: a pinned vertex must stay put even if a force is inf.
            let free = force_scale[lane] > 0.0;
            let new_delta = if free { moved } else { 0.0 };
            let new = if free { x[lane] + new_delta } else { x[lane] };
            delta[lane] = new_delta;
            next[lane] = new;
            probe[lane] += new * 0.0;
        }
    }
    probe
}

/// One slice's outputs: the next positions and the position deltas.
struct SliceOut<'a> {
    next: [&'a mut Block; 3],
    delta: [&'a mut Block; 3],
}

/// Iterates a chunk's outputs slice by slice.
fn slice_outputs<'a>(chunk: VertexChunk<'a>) -> impl Iterator<Item = (usize, SliceOut<'a>)> {
    let [nx, ny, nz] = chunk.next;
    let [dx, dy, dz] = chunk.delta;
    let first = chunk.first_slice;
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

#[inline(always)]
fn add_extra(force: &mut [Block; 3], extra: Option<&Soa>, slice: usize) {
    if let Some(extra) = extra {
        for (f, e) in force.iter_mut().zip(&extra.axes) {
            for lane in 0..LANES {
                f[lane] += e[slice][lane];
            }
        }
    }
}

fn probe_is_finite(probe: &Block) -> bool {
    probe.iter().all(|p| *p == 0.0)
}

/// A vertex-pass chunk: its first slice, where its next positions go and its deltas.
#[derive(Debug)]
pub struct VertexChunk<'a> {
    pub first_slice: usize,
    pub next: [&'a mut [Block]; 3],
    pub delta: [&'a mut [Block]; 3],
}

/// A chunk of per-slice force output (phase-separated steps).
#[derive(Debug)]
pub struct ForceChunk<'a> {
    pub first_slice: usize,
    pub out: [&'a mut [Block]; 3],
}

/// Gather (PCA), fused: spring forces of each slice's vertices, then Verlet, in one pass.
/// Returns false if a new position in the chunk is not finite.
#[multiversion(targets("x86_64+avx512f+avx512vl+avx512dq", "x86_64+avx2+fma", "aarch64+neon"))]
pub fn gather_and_integrate(
    table: &GatherTable,
    integrator: &Integrator,
    current: &Soa,
    extra: Option<&Soa>,
    chunk: VertexChunk<'_>,
) -> bool {
    let mut probe = [0.0f32; LANES];
    for (slice, out) in slice_outputs(chunk) {
        let mut force = gather_slice(table, current, slice);
        add_extra(&mut force, extra, slice);
        let p = integrate_slice(integrator, current, slice, &force, out);
        for lane in 0..LANES {
            probe[lane] += p[lane];
        }
    }
    probe_is_finite(&probe)
}

/// Scatter (ECA) accumulation by incidence, fused with Verlet: each vertex sums the precomputed
/// forces of its springs in a fixed order (deterministic for any thread count), then integrates.
#[multiversion(targets("x86_64+avx512f+avx512vl+avx512dq", "x86_64+avx2+fma", "aarch64+neon"))]
pub fn accumulate_and_integrate(
    table: &IncidenceTable,
    spring_forces: &Soa,
    integrator: &Integrator,
    current: &Soa,
    extra: Option<&Soa>,
    chunk: VertexChunk<'_>,
) -> bool {
    let mut probe = [0.0f32; LANES];
    for (slice, out) in slice_outputs(chunk) {
        let mut force = accumulate_slice(table, spring_forces, slice);
        add_extra(&mut force, extra, slice);
        let p = integrate_slice(integrator, current, slice, &force, out);
        for lane in 0..LANES {
            probe[lane] += p[lane];
        }
    }
    probe_is_finite(&probe)
}

/// Scatter (ECA) force pass: each spring's force on its `a` end, computed once, for rows
/// `first_row..first_row + out.len()`.
#[multiversion(targets("x86_64+avx512f+avx512vl+avx512dq", "x86_64+avx2+fma", "aarch64+neon"))]
pub fn spring_forces(
    springs: &SpringTable,
    current: &Soa,
    first_row: usize,
    out: [&mut [Block]; 3],
) {
    let [xs, ys, zs] = current.axes.each_ref().map(|a| a.as_flattened());
    let [ox, oy, oz] = out;
    for (k, ((fx, fy), fz)) in ox
        .iter_mut()
        .zip(oy.iter_mut())
        .zip(oz.iter_mut())
        .enumerate()
    {
        let row = first_row + k;
        let (a, b, rest) = (&springs.a[row], &springs.b[row], &springs.rest_length[row]);
        for lane in 0..LANES {
            let (i, j) = (a[lane] as usize, b[lane] as usize);
            // SAFETY: `CpuSolver::new` builds spring ends from the numbering: `i, j < padded_len`.
            let (dx, dy, dz) = unsafe {
                (
                    *xs.get_unchecked(j) - *xs.get_unchecked(i),
                    *ys.get_unchecked(j) - *ys.get_unchecked(i),
                    *zs.get_unchecked(j) - *zs.get_unchecked(i),
                )
            };
            let k = spring_scale(
                stiffness_at(&springs.stiffness, row, lane),
                rest[lane],
                dx * dx + dy * dy + dz * dz,
            );
            fx[lane] = k * dx;
            fy[lane] = k * dy;
            fz[lane] = k * dz;
        }
    }
}

/// Phase-separated gather (for per-phase timing): net spring force per vertex into `chunk.out`.
#[multiversion(targets("x86_64+avx512f+avx512vl+avx512dq", "x86_64+avx2+fma", "aarch64+neon"))]
pub fn gather_forces(table: &GatherTable, current: &Soa, chunk: ForceChunk<'_>) {
    let [ox, oy, oz] = chunk.out;
    for (k, ((bx, by), bz)) in ox
        .iter_mut()
        .zip(oy.iter_mut())
        .zip(oz.iter_mut())
        .enumerate()
    {
        let [fx, fy, fz] = gather_slice(table, current, chunk.first_slice + k);
        (*bx, *by, *bz) = (fx, fy, fz);
    }
}

/// Phase-separated scatter accumulation (for per-phase timing): net force per vertex.
#[multiversion(targets("x86_64+avx512f+avx512vl+avx512dq", "x86_64+avx2+fma", "aarch64+neon"))]
pub fn accumulate_forces(table: &IncidenceTable, spring_forces: &Soa, chunk: ForceChunk<'_>) {
    let [ox, oy, oz] = chunk.out;
    for (k, ((bx, by), bz)) in ox
        .iter_mut()
        .zip(oy.iter_mut())
        .zip(oz.iter_mut())
        .enumerate()
    {
        let [fx, fy, fz] = accumulate_slice(table, spring_forces, chunk.first_slice + k);
        (*bx, *by, *bz) = (fx, fy, fz);
    }
}

/// Phase-separated Verlet (for per-phase timing) from net per-vertex forces.
#[multiversion(targets("x86_64+avx512f+avx512vl+avx512dq", "x86_64+avx2+fma", "aarch64+neon"))]
pub fn integrate(
    integrator: &Integrator,
    current: &Soa,
    forces: &Soa,
    extra: Option<&Soa>,
    chunk: VertexChunk<'_>,
) -> bool {
    let mut probe = [0.0f32; LANES];
    for (slice, out) in slice_outputs(chunk) {
        let mut force = forces.axes.each_ref().map(|a| a[slice]);
        add_extra(&mut force, extra, slice);
        let p = integrate_slice(integrator, current, slice, &force, out);
        for lane in 0..LANES {
            probe[lane] += p[lane];
        }
    }
    probe_is_finite(&probe)
}
