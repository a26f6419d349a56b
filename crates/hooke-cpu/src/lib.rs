//! hooke-cpu: the fast float32 CPU solver, multithreaded with rayon, with the paper's two data
//! structures chosen at run time (Section 4):
//!
//! - [`Method::Gather`] (PCA, 4.1): each vertex loops over its springs and sums their forces,
//!   so every spring force is computed twice; then Verlet. One pass over the vertices.
//! - [`Method::Scatter`] (ECA, 4.2): each spring force is computed once into a force buffer; then
//!   each vertex accumulates the forces of its incident springs (the "incidence" accumulation:
//!   a fixed per-vertex order instead of atomics, so results are bit-identical across runs and
//!   thread counts) and integrates. Two passes.
//!
//! Both use the same spring arithmetic and the same per-vertex summation order, so gather and
//! scatter produce bit-identical states; see [`kernels`] for why.
#![allow(unsafe_code)] // Unchecked gathers in `kernels`; every index is checked when tables are built.

mod external;
pub mod kernels;
mod lanes;
pub mod layout;
pub mod simd;

use std::time::Instant;

use glam::{DVec3, Vec3};
pub use hooke_core::PhaseTimes;
use hooke_core::collide::{self, Collider};
use hooke_core::{Model, SimError, SimParams, Solver, State, selfcollide};
use rayon::prelude::*;

use external::ExternalForces;
use kernels::{
    B_END, Block, ForceChunk, GatherTable, IncidenceTable, IndexRows, InstructionSet, Integrator,
    Soa, SpringTable, Stiffness, VertexChunk,
};
use lanes::Lanes;
use layout::{LANES, Numbering, Slices, VertexOrder};

/// Which of the paper's data structures computes the spring forces.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum Method {
    Gather,
    Scatter,
}

impl Method {
    pub const ALL: [Method; 2] = [Method::Gather, Method::Scatter];

    pub fn name(self) -> &'static str {
        match self {
            Self::Gather => "gather",
            Self::Scatter => "scatter",
        }
    }
}

/// How to build a [`CpuSolver`].
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct CpuOptions {
    pub method: Method,
    /// Worker threads; `None` uses rayon's default (one per core, or `RAYON_NUM_THREADS`).
    pub threads: Option<usize>,
    pub order: VertexOrder,
    pub instruction_set: InstructionSet,
}

impl Default for CpuOptions {
    fn default() -> Self {
        Self {
            method: Method::Scatter,
            threads: None,
            order: VertexOrder::Mesh,
            instruction_set: InstructionSet::Best,
        }
    }
}

#[derive(Debug, thiserror::Error)]
pub enum CpuError {
    #[error("could not start {threads} worker threads: {source}")]
    ThreadPool {
        threads: usize,
        source: rayon::ThreadPoolBuildError,
    },
}

/// Bytes the solver holds, by role (the paper's Table 1 from the real allocations).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct MemoryUse {
    /// Current and previous positions.
    pub positions: usize,
    /// Adjacency (gather) or springs plus incidence (scatter).
    pub topology: usize,
    /// Per-spring force buffer (scatter) and per-vertex integration constants.
    pub per_step: usize,
}

impl MemoryUse {
    pub fn total(&self) -> usize {
        self.positions + self.topology + self.per_step
    }
}

/// Vertex slices per parallel task: 1024 vertices, small enough to balance two threads on the
/// smallest benchmark mesh and large enough that task overhead stays well under 1%.
const SLICES_PER_TASK: usize = 128;
/// Spring rows per parallel task (4096 springs).
const SPRING_ROWS_PER_TASK: usize = 512;

enum Topology {
    Gather(GatherTable),
    Scatter {
        springs: SpringTable,
        incidence: IncidenceTable,
        /// One row more than `springs`: the last row stays zero for padding entries.
        spring_forces: Soa,
    },
}

/// The float32 multithreaded solver.
pub struct CpuSolver {
    options: CpuOptions,
    /// Shared so a whole batch of steps can run inside one `install` (workers stay awake).
    pool: std::sync::Arc<rayon::ThreadPool>,
    model: Model,
    numbering: Numbering,
    topology: Topology,
    integrator: Integrator,
    params: SimParams,
    external: Option<ExternalForces>,
    extra_forces: Soa,
    /// Per-vertex net force, used only by the phase-separated step.
    phase_forces: Soa,
    /// `x(t)`.
    current: Soa,
    /// Receives `x(t + dt)`; swapped with `current` after each step.
    next: Soa,
    /// `x(t) - x(t - dt)`, updated in place (see [`kernels`] for why not `x(t - dt)`).
    delta: Soa,
    /// Self-collision weights by mesh vertex.
    inverse_masses: Vec<f32>,
    /// Colliders as they are now (dynamic balls move; scripted ones are placed by time).
    colliders: Vec<Collider>,
    /// Scratch of `collide`: per slice and collider, the momentum the cloth took.
    slice_pushes: Vec<DVec3>,
    steps_taken: u64,
}

impl std::fmt::Debug for CpuSolver {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str(&self.describe())
    }
}

fn into_blocks<T: Copy + Default>(values: Vec<T>) -> Vec<[T; LANES]> {
    values
        .chunks(LANES)
        .map(|c| std::array::from_fn(|lane| c.get(lane).copied().unwrap_or_default()))
        .collect()
}

impl CpuSolver {
    pub fn new(model: &Model, params: &SimParams, options: CpuOptions) -> Result<Self, CpuError> {
        let mut builder = rayon::ThreadPoolBuilder::new().thread_name(|i| format!("hooke-cpu-{i}"));
        if let Some(threads) = options.threads {
            builder = builder.num_threads(threads);
        }
        let pool = builder.build().map_err(|source| CpuError::ThreadPool {
            threads: options.threads.unwrap_or(0),
            source,
        })?;
        let numbering = Numbering::new(model, options.order);
        let slices = numbering.slice_count();
        let topology = match options.method {
            Method::Gather => Topology::Gather(gather_table(model, &numbering)),
            Method::Scatter => {
                let (springs, incidence) = scatter_tables(model, &numbering);
                let spring_forces = Soa::zeros(springs.a.len() + 1);
                Topology::Scatter {
                    springs,
                    incidence,
                    spring_forces,
                }
            }
        };
        let mut solver = Self {
            options,
            pool: std::sync::Arc::new(pool),
            numbering,
            topology,
            integrator: Integrator {
                scales: Lanes::default(),
                gravity_step: [0.0; 3],
            },
            params: params.clone(),
            external: None,
            extra_forces: Soa::default(),
            phase_forces: Soa::default(),
            current: Soa::zeros(slices),
            next: Soa::zeros(slices),
            delta: Soa::zeros(slices),
            inverse_masses: selfcollide::inverse_masses(model),
            colliders: params.colliders.clone(),
            slice_pushes: Vec::new(),
            model: model.clone(),
            steps_taken: 0,
        };
        solver.set_params(params);
        solver.write_state(&State::at_rest(model.initial_positions.clone()));
        Ok(solver)
    }

    pub fn options(&self) -> CpuOptions {
        self.options
    }

    pub fn threads(&self) -> usize {
        self.pool.current_num_threads()
    }

    pub fn memory(&self) -> MemoryUse {
        let positions = self.current.bytes() + self.next.bytes() + self.delta.bytes();
        let integration = 2 * self.numbering.slice_count() * std::mem::size_of::<Block>();
        let external = self
            .external
            .as_ref()
            .map_or(0, |e| e.bytes() + self.extra_forces.bytes());
        let (topology, forces) = match &self.topology {
            Topology::Gather(t) => (
                t.neighbor.bytes()
                    + std::mem::size_of_val(t.rest_length.as_slice())
                    + t.stiffness.bytes()
                    + std::mem::size_of_val(t.slices.slice_rows.as_slice()),
                0,
            ),
            Topology::Scatter {
                springs,
                incidence,
                spring_forces,
            } => (
                springs.a.bytes()
                    + springs.b.bytes()
                    + std::mem::size_of_val(springs.rest_length.as_slice())
                    + springs.stiffness.bytes()
                    + incidence.entry.bytes()
                    + std::mem::size_of_val(incidence.slices.slice_rows.as_slice()),
                spring_forces.bytes(),
            ),
        };
        MemoryUse {
            positions,
            topology,
            per_step: forces + integration + external,
        }
    }

    /// Bytes one fused step must read or write at least once (the memory-bandwidth floor).
    pub fn bytes_per_step(&self) -> usize {
        // Positions: read current, write next; deltas: read and write. Integration constants: read.
        let vertex_streams = self.current.bytes() * 4
            + 2 * self.numbering.slice_count() * std::mem::size_of::<Block>();
        vertex_streams
            + match &self.topology {
                Topology::Gather(t) => {
                    t.neighbor.bytes()
                        + std::mem::size_of_val(t.rest_length.as_slice())
                        + t.stiffness.bytes()
                }
                Topology::Scatter {
                    springs,
                    incidence,
                    spring_forces,
                } => {
                    springs.a.bytes()
                        + springs.b.bytes()
                        + std::mem::size_of_val(springs.rest_length.as_slice())
                        + springs.stiffness.bytes()
                        + incidence.entry.bytes()
                        // written once by the force pass, read back by the accumulation
                        + 2 * spring_forces.bytes()
                }
            }
    }

    fn compute_external(&mut self) -> bool {
        match &mut self.external {
            Some(external) => {
                let (current, delta, out) = (&self.current, &self.delta, &mut self.extra_forces);
                external.compute(current, delta, out);
                true
            }
            None => false,
        }
    }

    /// One fused step; runs its parallel passes in the current rayon pool (callers install ours).
    fn step_fused(&mut self) -> Result<(), SimError> {
        let isa = self.options.instruction_set;
        let has_extra = self.compute_external();
        let extra = has_extra.then_some(&self.extra_forces);
        let (current, integrator) = (&self.current, &self.integrator);
        let all_finite = match &mut self.topology {
            Topology::Gather(table) => {
                for_each_vertex_chunk(&mut self.next, &mut self.delta, |chunk| {
                    kernels::gather_and_integrate(isa, table, integrator, current, extra, chunk)
                })
            }
            Topology::Scatter {
                springs,
                incidence,
                spring_forces,
            } => {
                compute_spring_forces(isa, springs, current, spring_forces);
                let spring_forces = &*spring_forces;
                for_each_vertex_chunk(&mut self.next, &mut self.delta, |chunk| {
                    kernels::accumulate_and_integrate(
                        isa,
                        incidence,
                        spring_forces,
                        integrator,
                        current,
                        extra,
                        chunk,
                    )
                })
            }
        };
        let bad_ball = self.collide();
        self.self_collide();
        self.finish_step(all_finite)?;
        self.check_balls(bad_ball)
    }

    /// Reports a dynamic ball that `collide` found non-finite, at the step just finished.
    fn check_balls(&self, bad_ball: Option<usize>) -> Result<(), SimError> {
        match bad_ball {
            Some(collider) => Err(SimError::BallNonFinite {
                step: self.steps_taken,
                collider,
            }),
            None => Ok(()),
        }
    }

    /// Parts vertices that came too close to each other (see `hooke_core::selfcollide`), in
    /// mesh order so every solver sorts the same keys the same way.
    fn self_collide(&mut self) {
        let Some(config) = self.params.self_collision else {
            return;
        };
        let internal = &self.numbering.internal;
        let mut positions: Vec<Vec3> = internal
            .iter()
            .map(|&k| Vec3::from_array(self.next.get(k as usize)))
            .collect();
        let moves = selfcollide::resolve(
            &mut positions,
            &self.inverse_masses,
            &self.model.adjacency,
            &config,
        );
        // Only moved vertices are written back; each move shifts the step's motion too.
        for (v, c) in moves {
            let k = internal[v as usize] as usize;
            self.next
                .set(k, (Vec3::from_array(self.next.get(k)) + c).to_array());
            self.delta
                .set(k, (Vec3::from_array(self.delta.get(k)) + c).to_array());
        }
    }

    /// Moves vertices that ended inside a collider out of it (see `hooke_core::collide`), in
    /// parallel over vertex chunks, before the new positions become current; then advances
    /// dynamic balls by the momentum the cloth took from them. Returns the first ball that
    /// became non-finite.
    fn collide(&mut self) -> Option<usize> {
        if self.colliders.is_empty() {
            return None;
        }
        let (colliders, thickness) = (&self.colliders, self.params.collision_thickness);
        // Colliders are placed where they are at the end of the step being finished.
        let (dt, t) = (
            self.params.dt,
            (self.steps_taken + 1) as f64 * self.params.dt,
        );
        let (current, scales) = (&self.current, &self.integrator.scales);
        let (real, count) = (self.model.vertex_count(), colliders.len());
        let (masses, original) = (&self.model.masses, &self.numbering.original);
        let [nx, ny, nz] = self.next.axes_mut();
        let [dx, dy, dz] = self.delta.axes_mut();
        let free = scales.axis(0);
        let [cx, cy, cz] = current.axes();
        // Per slice and collider: sum of m c over the slice's vertices (kg m).
        self.slice_pushes.clear();
        self.slice_pushes.resize(free.len() * count, DVec3::ZERO);
        nx.par_iter_mut()
            .zip(ny.par_iter_mut())
            .zip(nz.par_iter_mut())
            .zip(
                dx.par_iter_mut()
                    .zip(dy.par_iter_mut())
                    .zip(dz.par_iter_mut()),
            )
            .zip(self.slice_pushes.par_chunks_mut(count))
            .enumerate()
            .for_each(|(slice, ((((nx, ny), nz), ((dx, dy), dz)), pushes))| {
                for lane in 0..LANES {
                    let k = slice * LANES + lane;
                    if k >= real || free[slice][lane] <= 0.0 {
                        continue;
                    }
                    let x = DVec3::new(
                        cx[slice][lane].into(),
                        cy[slice][lane].into(),
                        cz[slice][lane].into(),
                    );
                    let next = DVec3::new(nx[lane].into(), ny[lane].into(), nz[lane].into());
                    let mass = masses[original[k] as usize];
                    let p = collide::resolve_and_report(
                        colliders,
                        thickness,
                        t,
                        dt,
                        x,
                        next,
                        |c, moved| pushes[c] += moved * mass,
                    )
                    .as_vec3();
                    (nx[lane], ny[lane], nz[lane]) = (p.x, p.y, p.z);
                    let d = p - x.as_vec3();
                    (dx[lane], dy[lane], dz[lane]) = (d.x, d.y, d.z);
                }
            });
        if collide::any_dynamic(&self.colliders) {
            // Summed in slice order: the same result for any thread count.
            let mut pushes = vec![DVec3::ZERO; count];
            for chunk in self.slice_pushes.chunks(count) {
                for (total, push) in pushes.iter_mut().zip(chunk) {
                    *total += *push;
                }
            }
            collide::advance_balls(&mut self.colliders, &pushes, self.params.gravity, dt, t);
        }
        collide::first_non_finite_ball(&self.colliders)
    }

    /// One step with every phase as its own pass, timed. Results equal [`Solver::step`]'s.
    pub fn step_phased(&mut self) -> Result<PhaseTimes, SimError> {
        let isa = self.options.instruction_set;
        if self.phase_forces.blocks() != self.numbering.slice_count() {
            self.phase_forces = Soa::zeros(self.numbering.slice_count());
        }
        let mut times = PhaseTimes::default();
        let start = Instant::now();
        let pool = std::sync::Arc::clone(&self.pool);
        let has_extra = pool.install(|| self.compute_external());
        times.external = start.elapsed();
        let extra = has_extra.then_some(&self.extra_forces);
        let (current, integrator) = (&self.current, &self.integrator);
        let phase_forces = &mut self.phase_forces;
        let pool = std::sync::Arc::clone(&self.pool);
        let all_finite = pool.install(|| {
            let start = Instant::now();
            match &mut self.topology {
                Topology::Gather(table) => {
                    for_each_force_chunk(phase_forces, |chunk| {
                        kernels::gather_forces(isa, table, current, chunk)
                    });
                    times.force_calculation = start.elapsed();
                }
                Topology::Scatter {
                    springs,
                    incidence,
                    spring_forces,
                } => {
                    compute_spring_forces(isa, springs, current, spring_forces);
                    times.force_calculation = start.elapsed();
                    let start = Instant::now();
                    let spring_forces = &*spring_forces;
                    for_each_force_chunk(phase_forces, |chunk| {
                        kernels::accumulate_forces(isa, incidence, spring_forces, chunk);
                    });
                    times.force_accumulation = Some(start.elapsed());
                }
            }
            let start = Instant::now();
            let phase_forces = &*phase_forces;
            let all_finite = for_each_vertex_chunk(&mut self.next, &mut self.delta, |chunk| {
                kernels::integrate(isa, integrator, current, phase_forces, extra, chunk)
            });
            times.integration = start.elapsed();
            all_finite
        });
        let start = Instant::now();
        let bad_ball = pool.install(|| {
            let bad_ball = self.collide();
            self.self_collide();
            bad_ball
        });
        times.collision = start.elapsed();
        self.finish_step(all_finite)?;
        self.check_balls(bad_ball)?;
        Ok(times)
    }

    fn finish_step(&mut self, all_finite: bool) -> Result<(), SimError> {
        std::mem::swap(&mut self.current, &mut self.next);
        self.steps_taken += 1;
        if all_finite {
            return Ok(());
        }
        let vertex = (0..self.model.vertex_count())
            .find(|&v| {
                let k = self.numbering.internal[v] as usize;
                !self.current.get(k).iter().all(|x| x.is_finite())
            })
            .unwrap_or(0);
        Err(SimError::NonFinite {
            step: self.steps_taken,
            vertex,
        })
    }
}

/// Runs `kernel` over chunks of [`SLICES_PER_TASK`] slices of `next` and `delta` in parallel;
/// true if every chunk reported finite results.
fn for_each_vertex_chunk(
    next: &mut Soa,
    delta: &mut Soa,
    kernel: impl Fn(VertexChunk<'_>) -> bool + Sync,
) -> bool {
    let [nx, ny, nz] = next.axes_mut();
    let [dx, dy, dz] = delta.axes_mut();
    nx.par_chunks_mut(SLICES_PER_TASK)
        .zip(ny.par_chunks_mut(SLICES_PER_TASK))
        .zip(nz.par_chunks_mut(SLICES_PER_TASK))
        .zip(
            dx.par_chunks_mut(SLICES_PER_TASK)
                .zip(dy.par_chunks_mut(SLICES_PER_TASK))
                .zip(dz.par_chunks_mut(SLICES_PER_TASK)),
        )
        .enumerate()
        .map(|(task, (((nx, ny), nz), ((dx, dy), dz)))| {
            kernel(VertexChunk {
                first_slice: task * SLICES_PER_TASK,
                next: [nx, ny, nz],
                delta: [dx, dy, dz],
            })
        })
        .reduce(|| true, |a, b| a && b)
}

/// Runs a force-only `kernel` over chunks of [`SLICES_PER_TASK`] slices of `out` in parallel.
fn for_each_force_chunk(out: &mut Soa, kernel: impl Fn(ForceChunk<'_>) + Sync) {
    let [x, y, z] = out.axes_mut();
    x.par_chunks_mut(SLICES_PER_TASK)
        .zip(y.par_chunks_mut(SLICES_PER_TASK))
        .zip(z.par_chunks_mut(SLICES_PER_TASK))
        .enumerate()
        .for_each(|(task, ((x, y), z))| {
            kernel(ForceChunk {
                first_slice: task * SLICES_PER_TASK,
                out: [x, y, z],
            });
        });
}

fn compute_spring_forces(
    isa: InstructionSet,
    springs: &SpringTable,
    current: &Soa,
    spring_forces: &mut Soa,
) {
    let rows = springs.a.len();
    let [x, y, z] = spring_forces.axes_mut();
    x[..rows]
        .par_chunks_mut(SPRING_ROWS_PER_TASK)
        .zip(y[..rows].par_chunks_mut(SPRING_ROWS_PER_TASK))
        .zip(z[..rows].par_chunks_mut(SPRING_ROWS_PER_TASK))
        .enumerate()
        .for_each(|(task, ((x, y), z))| {
            kernels::spring_forces(
                isa,
                springs,
                current,
                task * SPRING_ROWS_PER_TASK,
                [x, y, z],
            );
        });
}

fn stiffness_of(model: &Model, per_entry: impl FnOnce() -> Vec<f32>) -> Stiffness {
    match model.stiffnesses.first() {
        Some(&first) if model.stiffnesses.iter().all(|k| *k == first) => {
            Stiffness::uniform(first as f32)
        }
        _ => Stiffness::per_entry(into_blocks(per_entry())),
    }
}

fn gather_table(model: &Model, numbering: &Numbering) -> GatherTable {
    let adjacency = &model.adjacency;
    let (slices, entries) = Slices::build(
        model,
        numbering,
        |_, e| {
            let spring = adjacency.springs[e] as usize;
            let neighbor = numbering.internal[adjacency.neighbors[e] as usize];
            (
                neighbor,
                model.rest_lengths[spring] as f32,
                model.stiffnesses[spring] as f32,
            )
        },
        |k| (k as u32, 0.0, 0.0),
    );
    GatherTable {
        slices,
        neighbor: IndexRows::new(
            into_blocks(entries.iter().map(|e| e.0).collect()),
            u32::MAX,
            numbering.padded_len,
        ),
        rest_length: into_blocks(entries.iter().map(|e| e.1).collect()),
        stiffness: stiffness_of(model, || entries.iter().map(|e| e.2).collect()),
    }
}

/// The order the scatter force pass visits springs in. Structured meshes have a handful of
/// index offsets `b - a` (3 on a grid); grouping springs by offset, then by `a`, makes both
/// ends of 8 consecutive springs consecutive vertices, so a row loads with vector loads. Other
/// meshes are ordered by first end, which keeps position reads nearly sequential.
fn spring_order(ends: &[[u32; 2]]) -> Vec<u32> {
    const MAX_CLASSES: usize = 16;
    let offset = |s: u32| i64::from(ends[s as usize][1]) - i64::from(ends[s as usize][0]);
    let mut counts = std::collections::HashMap::<i64, usize>::new();
    for s in 0..ends.len() as u32 {
        *counts.entry(offset(s)).or_default() += 1;
    }
    let mut common: Vec<(usize, i64)> = counts.iter().map(|(o, c)| (*c, *o)).collect();
    common.sort_unstable_by(|a, b| b.cmp(a));
    common.truncate(MAX_CLASSES);
    let covered: usize = common.iter().map(|(c, _)| c).sum();
    let mut order: Vec<u32> = (0..ends.len() as u32).collect();
    if covered * 10 >= ends.len() * 9 {
        let class: std::collections::HashMap<i64, usize> = common
            .iter()
            .enumerate()
            .map(|(rank, (_, o))| (*o, rank))
            .collect();
        let key = |s: u32| {
            let [a, b] = ends[s as usize];
            (class.get(&offset(s)).copied().unwrap_or(MAX_CLASSES), a, b)
        };
        order.sort_by_cached_key(|&s| key(s));
    } else {
        order.sort_by_key(|&s| {
            let [a, b] = ends[s as usize];
            (a.min(b), a.max(b))
        });
    }
    order
}

fn scatter_tables(model: &Model, numbering: &Numbering) -> (SpringTable, IncidenceTable) {
    let ends: Vec<[u32; 2]> = model
        .spring_ends
        .iter()
        .map(|e| {
            let [a, b] = e.map(|v| numbering.internal[v as usize]);
            [a.min(b), a.max(b)]
        })
        .collect();
    // `slot_of[s]` is model spring s's place in the force pass and force buffer.
    let order = spring_order(&ends);
    let mut slot_of = vec![0u32; model.spring_count()];
    for (slot, &s) in order.iter().enumerate() {
        slot_of[s as usize] = slot as u32;
    }
    let rows = model.spring_count().div_ceil(LANES);
    let zero_slot = (rows * LANES) as u32;
    let end_rows = |end: usize| {
        IndexRows::new(
            into_blocks(order.iter().map(|&s| ends[s as usize][end]).collect()),
            u32::MAX,
            numbering.padded_len,
        )
    };
    let springs = SpringTable {
        a: end_rows(0),
        b: end_rows(1),
        rest_length: into_blocks(
            order
                .iter()
                .map(|&s| model.rest_lengths[s as usize] as f32)
                .collect(),
        ),
        stiffness: stiffness_of(model, || {
            order
                .iter()
                .map(|&s| model.stiffnesses[s as usize] as f32)
                .collect()
        }),
    };
    let adjacency = &model.adjacency;
    let (slices, entries) = Slices::build(
        model,
        numbering,
        |k, e| {
            let spring = adjacency.springs[e] as usize;
            let is_b_end = ends[spring][1] as usize == k;
            slot_of[spring] | if is_b_end { B_END } else { 0 }
        },
        |_| zero_slot,
    );
    let incidence = IncidenceTable {
        slices,
        entry: IndexRows::new(into_blocks(entries), !B_END, zero_slot as usize + LANES),
    };
    (springs, incidence)
}

impl Solver for CpuSolver {
    fn describe(&self) -> String {
        let order = match self.options.order {
            VertexOrder::Mesh => "",
            VertexOrder::ValenceSorted => ", valence-sorted",
        };
        format!(
            "cpu {} (f32, {} threads{order})",
            self.options.method.name(),
            self.threads()
        )
    }

    fn set_params(&mut self, params: &SimParams) {
        let dt = params.dt;
        let per_vertex = |f: &dyn Fn(usize) -> f64| -> Vec<Block> {
            into_blocks(
                (0..self.numbering.padded_len)
                    .map(|k| {
                        self.numbering
                            .original
                            .get(k)
                            .map_or(0.0, |&v| f(v as usize) as f32)
                    })
                    .collect(),
            )
        };
        let free = |v: usize| !self.model.pinned[v];
        let force_scale = per_vertex(&|v| {
            if free(v) {
                dt * dt / self.model.masses[v]
            } else {
                0.0
            }
        });
        let velocity_scale = per_vertex(&|v| {
            if free(v) {
                1.0 - params.damping * dt / self.model.masses[v]
            } else {
                0.0
            }
        });
        self.integrator = Integrator {
            scales: Lanes::from_axes([force_scale, velocity_scale]),
            gravity_step: (params.gravity * dt * dt).as_vec3().to_array(),
        };
        self.external = ExternalForces::new(&self.model, &self.numbering, params);
        if self.external.is_some() && self.extra_forces.blocks() != self.numbering.slice_count() {
            self.extra_forces = Soa::zeros(self.numbering.slice_count());
        }
        self.colliders = collide::carry_over(&self.colliders, &params.colliders);
        self.params = params.clone();
    }

    fn step(&mut self, steps: u32) -> Result<(), SimError> {
        let pool = std::sync::Arc::clone(&self.pool);
        pool.install(|| {
            for _ in 0..steps {
                self.step_fused()?;
            }
            Ok(())
        })
    }

    fn read_state(&self) -> State {
        let read = |soa: &Soa, v: usize| {
            DVec3::from(soa.get(self.numbering.internal[v] as usize).map(f64::from))
        };
        let positions: Vec<DVec3> = (0..self.model.vertex_count())
            .map(|v| read(&self.current, v))
            .collect();
        let previous_positions = positions
            .iter()
            .enumerate()
            .map(|(v, x)| *x - read(&self.delta, v))
            .collect();
        State {
            positions,
            previous_positions,
        }
    }

    fn write_state(&mut self, state: &State) {
        for (v, (p, q)) in state
            .positions
            .iter()
            .zip(&state.previous_positions)
            .enumerate()
        {
            let k = self.numbering.internal[v] as usize;
            self.current.set(k, p.as_vec3().to_array());
            self.delta.set(k, (*p - *q).as_vec3().to_array());
        }
    }

    fn steps_taken(&self) -> u64 {
        self.steps_taken
    }

    fn colliders(&self) -> Vec<Collider> {
        collide::placed(&self.colliders, self.steps_taken as f64 * self.params.dt)
    }
}
