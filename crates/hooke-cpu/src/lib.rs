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

mod blocks;
mod collision;
mod early;
mod external;
pub mod kernels;
mod lanes;
pub mod layout;
mod owned_rows;
mod ring;
pub mod simd;
mod sweep;
mod tables;
mod view;

use std::time::Instant;

use glam::{DVec3, Vec3};
pub use hooke_core::PhaseTimes;
use hooke_core::collide::{self, Collider};
use hooke_core::selfcollide::SelfCollision;
use hooke_core::tearing::Tears;
use hooke_core::{
    Control, Material, Model, SimError, Snapshot, Solver, State, TimingSource, selfcollide,
};
use rayon::iter::Either;
use rayon::prelude::*;

use external::ExternalForces;
use kernels::{
    Block, ForceChunk, ForceRows, GatherTable, IncidenceTable, InstructionSet, Integrator, Point,
    Soa, SpringForces, SpringTable, VertexChunk,
};
use lanes::Lanes;
use layout::{LANES, Numbering, VertexOrder};
use simd::{Portable, Simd};
use tables::{build_topology, into_blocks, stiffness_entries};
use view::Positions;

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
            order: VertexOrder::Auto,
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
pub struct CpuMemory {
    /// Current and previous positions.
    pub positions: usize,
    /// Adjacency (gather) or springs plus incidence (scatter).
    pub topology: usize,
    /// Per-spring force buffer (scatter) and per-vertex integration constants.
    pub per_step: usize,
}

impl CpuMemory {
    pub fn total(&self) -> usize {
        self.positions + self.topology + self.per_step
    }
}

/// Vertex slices per parallel task: 1024 vertices, small enough to balance two threads on the
/// smallest benchmark mesh and large enough that task overhead stays well under 1%.
const SLICES_PER_TASK: usize = 128;
/// Spring rows per parallel task (4096 springs).
const SPRING_ROWS_PER_TASK: usize = 512;

#[allow(clippy::large_enum_variant)] // one per solver: boxing a variant would save nothing
enum Topology {
    Gather(GatherTable),
    Scatter {
        springs: SpringTable,
        incidence: IncidenceTable,
        /// One row more than `springs`: the last row stays zero for padding entries.
        spring_forces: SpringForces,
    },
}

impl Topology {
    /// Whether the force pass reads the positions as points: its rows mostly load lane by
    /// lane (gather's neighbour rows; scatter's incidence rows, whose spring forces are then
    /// points too).
    fn reads_points(&self) -> bool {
        match self {
            Self::Gather(table) => table.neighbor.mostly_gathered(),
            Self::Scatter { spring_forces, .. } => matches!(spring_forces, SpringForces::Points(_)),
        }
    }
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
    material: Material,
    control: Control,
    self_collision: Option<SelfCollision>,
    /// Self-collision's sort buffers and culling, kept between steps.
    self_collider: selfcollide::Resolver,
    external: Option<ExternalForces>,
    extra_forces: Soa,
    /// Per-vertex net force, used only by the phase-separated step.
    phase_forces: Soa,
    /// `x(t)`.
    current: Soa,
    /// Whether the force pass reads the positions as points (see [`Topology::reads_points`]).
    reads_points: bool,
    /// `x(t)` as one point per vertex, by slice, when the force pass reads them (else empty).
    points: Vec<[Point; LANES]>,
    /// Receives `x(t + dt)` as points from the integration; swapped with `points`.
    next_points: Vec<[Point; LANES]>,
    /// Whether `points` holds `x(t)`: the integration wrote them and nothing moved a vertex
    /// after it but self-collision, which moves them too (colliders and handles do not), or
    /// since (`write_state`).
    points_fresh: bool,
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
    /// Broken springs (their stiffness is zero in `topology`) and the tests that break more.
    tears: Tears,
    /// Scratch of `tear`: the current positions as one `Vec3` each.
    tear_positions: Vec<Vec3>,
    /// Where each spring's stiffness sits in `topology` (made when a spring first tears).
    stiffness_entries: Option<Vec<[u32; 2]>>,
    /// How several steps run in one sweep over memory, when they may (see [`sweep`]).
    sweep: Option<sweep::Sweep>,
    /// How a scatter step runs block by block on a large mesh (see [`blocks`]).
    blocks: Option<blocks::Blocks>,
    /// Where the spring forces of sweeps over `blocks` go, made at the first (see [`ring`]).
    force_ring: std::sync::OnceLock<Option<ring::ForceRing>>,
    /// The slices of the coming step that ran beside the last step's self-collision (see
    /// [`early`]).
    early: Option<early::Done>,
    /// Tests: run those slices as soon as the zone is offered, on the thread that offers it.
    #[cfg(test)]
    early_eagerly: bool,
    steps_taken: u64,
}

impl std::fmt::Debug for CpuSolver {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str(&self.describe())
    }
}

impl CpuSolver {
    /// A solver of `method` on `threads` threads for the unit tests, which then switch its
    /// step plans on or off.
    #[cfg(test)]
    pub(crate) fn for_test(
        scene: &hooke_core::scene::Scene,
        method: Method,
        threads: usize,
    ) -> Self {
        let options = CpuOptions {
            method,
            threads: Some(threads),
            ..Default::default()
        };
        Self::new(&scene.model, &scene.material, options).expect("solver")
    }

    /// Steps `self` and `other` by each of `steps` in turn, asserting after each that their
    /// states are the same bits (`what` names the case).
    #[cfg(test)]
    pub(crate) fn assert_steps_alike(&mut self, other: &mut Self, steps: &[u32], what: &str) {
        use hooke_core::Solver;
        for &n in steps {
            self.step(n).expect("stable");
            other.step(n).expect("stable");
            let (a, b) = (
                hooke_testkit::state_of(self),
                hooke_testkit::state_of(other),
            );
            assert!(a == b, "{what}, after {} steps", other.steps_taken());
        }
        assert_eq!(self.steps_taken(), other.steps_taken());
    }

    /// Steps until a result is not finite (within 100,000 steps); the step the error names,
    /// which must be the solver's count.
    #[cfg(test)]
    pub(crate) fn step_until_blown_up(&mut self) -> u64 {
        use hooke_core::Solver;
        let error = self.step(100_000).expect_err("must blow up");
        let SimError::NonFinite { step, .. } = error else {
            panic!("unexpected {error:?}");
        };
        assert_eq!(self.steps_taken(), step);
        step
    }

    pub fn new(model: &Model, material: &Material, options: CpuOptions) -> Result<Self, CpuError> {
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
        let topology = build_topology(model, &numbering, options.method, material.stiffness_scale);
        let self_collider = resolver_for(model, &numbering, model.collision.self_collision);
        let mut solver = Self {
            options,
            pool: std::sync::Arc::new(pool),
            numbering,
            topology,
            integrator: Integrator {
                scales: Lanes::default(),
                gravity_step: [0.0; 3],
            },
            material: *material,
            control: Control::default(),
            self_collision: model.collision.self_collision,
            self_collider,
            external: None,
            extra_forces: Soa::default(),
            phase_forces: Soa::default(),
            current: Soa::zeros(slices),
            reads_points: false,
            points: Vec::new(),
            next_points: Vec::new(),
            points_fresh: false,
            early: None,
            #[cfg(test)]
            early_eagerly: false,
            next: Soa::zeros(slices),
            delta: Soa::zeros(slices),
            inverse_masses: selfcollide::inverse_masses(model),
            colliders: model.collision.colliders.clone(),
            slice_pushes: Vec::new(),
            tears: Tears::new(model),
            tear_positions: Vec::new(),
            stiffness_entries: None,
            sweep: None,
            blocks: None,
            force_ring: std::sync::OnceLock::new(),
            model: model.clone(),
            steps_taken: 0,
        };
        solver.set_integrator();
        solver.set_points();
        solver.plan_sweep();
        // The model's dampers act before any control is given.
        solver.set_external_forces();
        solver.write_state(&State::at_rest(model.initial_positions.clone()));
        Ok(solver)
    }

    pub fn options(&self) -> CpuOptions {
        self.options
    }

    /// Per spring, true once broken (see [`hooke_core::tearing`]).
    pub fn broken_flags(&self) -> &[bool] {
        self.tears.flags()
    }

    /// How many springs have broken (kept as they break, not counted).
    pub fn broken_count(&self) -> usize {
        self.tears.count()
    }

    pub fn threads(&self) -> usize {
        self.pool.current_num_threads()
    }

    pub fn memory(&self) -> CpuMemory {
        let positions = self.current.bytes() + self.next.bytes() + self.delta.bytes();
        let integration = 2 * self.numbering.slice_count() * std::mem::size_of::<Block>();
        let external = self
            .external
            .as_ref()
            .map_or(0, |e| e.bytes() + self.extra_forces.bytes());
        let (topology, forces) = match &self.topology {
            Topology::Gather(t) => (
                t.neighbor.bytes()
                    + t.rest_length.bytes()
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
                    + springs.rest_length.bytes()
                    + springs.stiffness.bytes()
                    + incidence.entry.bytes()
                    + std::mem::size_of_val(incidence.slices.slice_rows.as_slice())
                    + incidence.tails.len(),
                spring_forces.bytes(),
            ),
        };
        CpuMemory {
            positions,
            topology,
            per_step: forces + self.points_bytes() + integration + external,
        }
    }

    /// Bytes of `points` and `next_points` when the force pass reads them.
    fn points_bytes(&self) -> usize {
        std::mem::size_of_val(self.points.as_slice())
            + std::mem::size_of_val(self.next_points.as_slice())
    }

    /// Sizes the point buffers for the topology: two rows of points per slice when its force
    /// pass reads them, else none.
    fn set_points(&mut self) {
        self.reads_points = self.topology.reads_points();
        let rows = if self.reads_points {
            self.numbering.slice_count()
        } else {
            0
        };
        for points in [&mut self.points, &mut self.next_points] {
            points.clear();
            points.resize(rows, [[0.0; 4]; LANES]);
        }
        self.points_fresh = false;
    }

    fn plan_sweep(&mut self) {
        let (slices, threads) = (self.numbering.slice_count(), self.threads());
        self.sweep = sweep::Sweep::plan(&self.topology, slices, threads);
        self.blocks = match &self.topology {
            Topology::Scatter {
                springs, incidence, ..
            } => blocks::Blocks::plan(springs, incidence, slices, threads),
            Topology::Gather(_) => None,
        };
    }

    /// Whether nothing acts between one step's spring forces and the next's but
    /// self-collision, if on: no tearing, external forces, colliders or handles.
    fn only_self_collision_between_steps(&self) -> bool {
        self.tears.rule().is_none() && self.external.is_none() && self.no_colliders_or_handles()
    }

    /// Whether no collider or handle moves a vertex after the integration (self-collision
    /// still may).
    fn no_colliders_or_handles(&self) -> bool {
        self.colliders.is_empty() && self.model.handles.is_empty()
    }

    /// Steps that `step(n)` advances per sweep over memory at most (see `sweep`): 2 to 6 on a
    /// mesh laid out to sweep while nothing acts between its steps, else 1.
    pub fn steps_per_sweep(&self) -> usize {
        if self.can_sweep() {
            self.sweep_depth()
        } else {
            1
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
                    t.neighbor.bytes() + t.rest_length.bytes() + t.stiffness.bytes()
                }
                Topology::Scatter {
                    springs,
                    incidence,
                    spring_forces,
                } => {
                    springs.a.bytes()
                        + springs.b.bytes()
                        + springs.rest_length.bytes()
                        + springs.stiffness.bytes()
                        + incidence.entry.bytes()
                        // written once by the force pass, read back by the accumulation
                        + 2 * spring_forces.bytes()
                }
            }
            // The points: written by the integration (or copied), read by the force pass.
            + self.points_bytes()
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

    /// One step; runs its parallel passes in the current rayon pool (callers install ours). The
    /// phases, in order: the control's forces, the spring forces (scatter: and their
    /// accumulation), integration, collision. With `times`, forces and integration run as
    /// separate passes, each timed; without, they are fused into one pass per vertex chunk,
    /// which keeps each vertex's force in registers. Both give bit-identical states.
    ///
    /// With `more` (another step follows in the same call, untimed), the next step's spring
    /// forces and integration may begin beside this step's self-collision (see [`early`]).
    fn step_once(
        &mut self,
        mut times: Option<&mut PhaseTimes>,
        more: bool,
    ) -> Result<(), SimError> {
        let start = Instant::now();
        self.tear();
        let tearing = start.elapsed();
        let start = Instant::now();
        let has_extra = self.compute_external();
        if let Some(times) = times.as_deref_mut() {
            times.external = start.elapsed();
        }
        let all_finite = match times.as_deref_mut() {
            None => self.forces_and_integration_fused(has_extra),
            Some(times) => {
                let all_finite = self.forces_then_integration(has_extra, times);
                // Testing springs for tearing is part of computing their forces.
                times.force_calculation += tearing;
                all_finite
            }
        };
        let start = Instant::now();
        let bad_ball = self.collide();
        self.move_handles();
        let early = more && times.is_none() && all_finite && self.can_step_early();
        let self_collision = self.self_collide(times.is_some(), early);
        if let Some(times) = times {
            times.collision = start.elapsed();
            times.self_collision = self_collision;
        }
        self.finish_step(all_finite)?;
        self.check_balls(bad_ball)
    }

    /// Breaks the springs the current positions stretch past their limits (in parallel, listed
    /// in spring order), and rebuilds the force tables without them when any broke.
    fn tear(&mut self) {
        let Some(rule) = self.tears.rule() else {
            return;
        };
        // Positions as one vec3 each (internal order): an edge test reads 12 contiguous bytes
        // per end instead of one float from each axis.
        let [xs, ys, zs] = self.current.axes();
        let (xs, ys, zs) = (xs.as_flattened(), ys.as_flattened(), zs.as_flattened());
        self.tear_positions.clear();
        self.tear_positions.par_extend(
            (0..xs.len())
                .into_par_iter()
                .map(|k| Vec3::new(xs[k], ys[k], zs[k])),
        );
        let (positions, internal) = (&self.tear_positions, &self.numbering.internal);
        let position = |v: u32| positions[internal[v as usize] as usize];
        // `tearing::newly_broken` with the edges tested in parallel; what breaks follows from
        // the few that pass.
        let passing: Vec<u32> = (0..rule.first_bending() as u32)
            .into_par_iter()
            .filter(|&e| rule.edge_breaks(e as usize, position))
            .collect();
        let newly = rule.breaking(&passing, self.tears.flags());
        if !newly.is_empty() {
            self.tears.mark(&newly);
            self.zero_stiffness(&newly);
            if self.model.bending_damping > 0.0 {
                self.set_external_forces();
            }
        }
    }

    /// Zeroes the stiffness of `springs` in the force tables, in place: the tables
    /// [`CpuSolver::build_tables`] would build with them torn, without building anything.
    fn zero_stiffness(&mut self, springs: &[u32]) {
        let entries = self.stiffness_entries.get_or_insert_with(|| {
            stiffness_entries(&self.model, &self.numbering, self.options.method)
        });
        let torn = springs
            .iter()
            .flat_map(|&s| entries[s as usize])
            .filter(|&e| e != u32::MAX)
            .map(|e| e as usize);
        match &mut self.topology {
            Topology::Gather(table) => {
                let count = table.rest_length.len() * LANES;
                table.stiffness.zero_entries(torn, count);
            }
            Topology::Scatter { springs, .. } => {
                let count = springs.rest_length.len() * LANES;
                springs.stiffness.zero_entries(torn, count);
            }
        }
    }

    /// The force tables of the model under the material's stiffness scale, torn springs at zero
    /// stiffness.
    fn build_tables(&mut self) {
        let scale = self.material.stiffness_scale;
        self.topology = if self.tears.count() == 0 {
            build_topology(&self.model, &self.numbering, self.options.method, scale)
        } else {
            let torn = self.model.with_springs_broken(self.tears.flags());
            build_topology(&torn, &self.numbering, self.options.method, scale)
        };
        self.set_points();
        self.plan_sweep();
    }

    /// Forces and integration in one pass per vertex chunk; true if every result is finite.
    fn forces_and_integration_fused(&mut self, has_extra: bool) -> bool {
        if let Some(done) = self.early.take() {
            return self.rest_of_early_step(done);
        }
        let isa = self.options.instruction_set;
        let points = self.refresh_points().then_some(self.points.as_flattened());
        let writes_points = self.writes_points();
        let next_points = writes_points.then_some(self.next_points.as_mut_slice());
        let extra = has_extra.then_some(&self.extra_forces);
        let (current, integrator) = (&self.current, &self.integrator);
        let (next, delta) = (&mut self.next, &mut self.delta);
        let all_finite = match &mut self.topology {
            Topology::Gather(table) => {
                let current = Positions::new(current, points);
                for_each_vertex_chunk(next, delta, next_points, |chunk| {
                    kernels::gather_and_integrate(isa, table, integrator, current, extra, chunk)
                })
            }
            Topology::Scatter {
                springs,
                incidence,
                spring_forces,
            } => {
                if let Some(blocks) = &self.blocks {
                    let out = blocks::Outputs::new(next, delta, next_points);
                    blocks.step(
                        isa,
                        springs,
                        incidence,
                        spring_forces,
                        integrator,
                        current,
                        points,
                        extra,
                        out,
                        &blocks::Begun::default(),
                    )
                } else {
                    compute_spring_forces(isa, springs, current, points, spring_forces);
                    let spring_forces = spring_forces.view();
                    let current = Positions::new(current, None);
                    for_each_vertex_chunk(next, delta, next_points, |chunk| {
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
            }
        };
        self.points_integrated(writes_points);
        all_finite
    }

    /// Whether the next step's spring forces and integration may begin beside this step's
    /// self-collision (see [`early`]): another thread to run it, a mesh large enough, gather
    /// or scatter block by block, reading the positions by axis, and nothing but
    /// self-collision acting between the steps' spring forces.
    fn can_step_early(&self) -> bool {
        let by_block = match self.topology {
            Topology::Gather(_) => true,
            Topology::Scatter { .. } => self.blocks.is_some(),
        };
        rayon::current_num_threads() > 1
            && self.numbering.slice_count() >= early::MIN_SLICES
            && by_block
            && !self.reads_points
            && self.only_self_collision_between_steps()
    }

    /// The fused step's slices (scatter: and force rows) that did not run beside the last
    /// step's self-collision (`done` did); true if every result of the step is finite.
    fn rest_of_early_step(&mut self, done: early::Done) -> bool {
        let isa = self.options.instruction_set;
        let slices = self.numbering.slice_count();
        if let Topology::Scatter {
            springs,
            incidence,
            spring_forces,
        } = &mut self.topology
        {
            let blocks = self
                .blocks
                .as_ref()
                .expect("only blocked scatter steps early");
            let mut begun = blocks::Begun {
                rows: done.rows,
                slices: vec![false; slices],
            };
            for range in done.ranges {
                begun.slices[range].fill(true);
            }
            let current = &self.current;
            let out = blocks::Outputs::new(&mut self.next, &mut self.delta, None);
            let finite = blocks.step(
                isa,
                springs,
                incidence,
                spring_forces,
                &self.integrator,
                current,
                None,
                None,
                out,
                &begun,
            );
            self.points_integrated(false);
            return finite && done.finite;
        }
        let left = early::left_over(&done.ranges, slices, SLICES_PER_TASK);
        let buffers = sweep::Buffers::of(self, false);
        let Topology::Gather(table) = &self.topology else {
            unreachable!("gather or scatter");
        };
        let kernel = sweep::gather_run(isa, table, &self.integrator);
        // SAFETY: step 1 of the buffers reads `current` and writes `next` and the deltas, each
        // task its own slices (`left` are disjoint); nothing else runs meanwhile.
        let finite = left
            .into_par_iter()
            .map(|slices| unsafe { buffers.step(1, slices, true, &kernel) })
            .reduce(|| true, |a, b| a && b);
        drop(kernel); // it borrows the tables, which `points_integrated` borrows with the rest
        self.points_integrated(false);
        finite && done.finite
    }

    /// Forces (and accumulation) into a per-vertex buffer, then integration, each pass timed.
    fn forces_then_integration(&mut self, has_extra: bool, times: &mut PhaseTimes) -> bool {
        let isa = self.options.instruction_set;
        if self.phase_forces.blocks() != self.numbering.slice_count() {
            self.phase_forces = Soa::zeros(self.numbering.slice_count());
        }
        let start = Instant::now();
        let points = self.refresh_points().then_some(self.points.as_flattened());
        let writes_points = self.writes_points();
        let next_points = writes_points.then_some(self.next_points.as_mut_slice());
        let extra = has_extra.then_some(&self.extra_forces);
        let (current, integrator) = (&self.current, &self.integrator);
        let phase_forces = &mut self.phase_forces;
        match &mut self.topology {
            Topology::Gather(table) => {
                for_each_force_chunk(phase_forces, |chunk| {
                    kernels::gather_forces(isa, table, current, points, chunk)
                });
                times.force_calculation = start.elapsed();
            }
            Topology::Scatter {
                springs,
                incidence,
                spring_forces,
            } => {
                compute_spring_forces(isa, springs, current, points, spring_forces);
                times.force_calculation = start.elapsed();
                let start = Instant::now();
                let spring_forces = spring_forces.view();
                for_each_force_chunk(phase_forces, |chunk| {
                    kernels::accumulate_forces(isa, incidence, spring_forces, chunk);
                });
                times.force_accumulation = Some(start.elapsed());
            }
        }
        let start = Instant::now();
        let phase_forces = &*phase_forces;
        let (next, delta) = (&mut self.next, &mut self.delta);
        let all_finite = for_each_vertex_chunk(next, delta, next_points, |chunk| {
            kernels::integrate(isa, integrator, current, phase_forces, extra, chunk)
        });
        times.integration = start.elapsed();
        self.points_integrated(writes_points);
        all_finite
    }

    /// Makes `points` hold `x(t)` when the force pass reads them: those the last integration
    /// wrote, else copied now. True if the force pass reads them.
    fn refresh_points(&mut self) -> bool {
        if !self.reads_points {
            return false;
        }
        if !self.points_fresh {
            let [xs, ys, zs] = self.current.axes();
            // Storing and loading points multiplies nothing: either portable kind gives the
            // same bits.
            self.points
                .par_iter_mut()
                .zip(xs.par_iter().zip(ys.par_iter()).zip(zs.par_iter()))
                .for_each(|(points, ((x, y), z))| {
                    Portable::<false>.store_points([*x, *y, *z], points);
                });
            self.points_fresh = true;
        }
        true
    }

    /// The positions from the points, where a sweep stopped before its last step (see
    /// `sweep::Buffers::step`).
    fn axes_from_points(&mut self) {
        let [xs, ys, zs] = self.current.axes_mut();
        self.points
            .par_iter()
            .zip(
                xs.par_iter_mut()
                    .zip(ys.par_iter_mut())
                    .zip(zs.par_iter_mut()),
            )
            .for_each(|(points, ((x, y), z))| {
                [*x, *y, *z] = Portable::<false>.load_points(points);
            });
    }

    /// Whether the integration should write the next positions as points: the force pass reads
    /// them, and nothing but self-collision will move a vertex after the integration
    /// (self-collision moves them in the points too, see `self_collide`, and reads them).
    fn writes_points(&self) -> bool {
        self.reads_points && self.no_colliders_or_handles()
    }

    /// After an integration: the points it wrote (if it did) are the next step's.
    fn points_integrated(&mut self, written: bool) {
        if written {
            std::mem::swap(&mut self.points, &mut self.next_points);
        }
        self.points_fresh = written;
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

    /// The external forces of the current control and dt, and the buffer they go into.
    fn set_external_forces(&mut self) {
        self.external = ExternalForces::new(
            &self.model,
            &self.numbering,
            &self.control,
            self.material.dt,
            self.tears.flags(),
        );
        if self.external.is_some() && self.extra_forces.blocks() != self.numbering.slice_count() {
            self.extra_forces = Soa::zeros(self.numbering.slice_count());
        }
    }

    /// The integration constants of the current material: `dt^2/m`, `1 - c dt/m` and `g dt^2`.
    fn set_integrator(&mut self) {
        let dt = self.material.dt;
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
                1.0 - self.material.damping * dt / self.model.masses[v]
            } else {
                0.0
            }
        });
        self.integrator = Integrator {
            scales: Lanes::from_axes([force_scale, velocity_scale]),
            gravity_step: (self.material.gravity * dt * dt).as_vec3().to_array(),
        };
    }

    fn finish_step(&mut self, all_finite: bool) -> Result<(), SimError> {
        std::mem::swap(&mut self.current, &mut self.next);
        self.steps_taken += 1;
        self.check_finite(all_finite)
    }

    /// The error for a step whose results were not all finite, naming the first vertex whose
    /// current position is not.
    fn check_finite(&self, all_finite: bool) -> Result<(), SimError> {
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
    next_points: Option<&mut [[Point; LANES]]>,
    kernel: impl Fn(VertexChunk<'_>) -> bool + Sync,
) -> bool {
    let [nx, ny, nz] = next.axes_mut();
    let [dx, dy, dz] = delta.axes_mut();
    // Each task's rows of points, or none for every task.
    let points = match next_points {
        Some(points) => Either::Left(points.par_chunks_mut(SLICES_PER_TASK).map(Some)),
        None => {
            let tasks = nx.len().div_ceil(SLICES_PER_TASK);
            Either::Right(rayon::iter::repeat_n((), tasks).map(|()| None))
        }
    };
    nx.par_chunks_mut(SLICES_PER_TASK)
        .zip(ny.par_chunks_mut(SLICES_PER_TASK))
        .zip(nz.par_chunks_mut(SLICES_PER_TASK))
        .zip(
            dx.par_chunks_mut(SLICES_PER_TASK)
                .zip(dy.par_chunks_mut(SLICES_PER_TASK))
                .zip(dz.par_chunks_mut(SLICES_PER_TASK)),
        )
        .zip(points)
        .enumerate()
        .map(|(task, ((((nx, ny), nz), ((dx, dy), dz)), points))| {
            kernel(VertexChunk {
                first_slice: task * SLICES_PER_TASK,
                next: [nx, ny, nz],
                axes: true,
                delta: [dx, dy, dz],
                points,
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
    points: Option<&[Point]>,
    spring_forces: &mut SpringForces,
) {
    let rows = springs.a.len();
    let pass = |task: usize, out: ForceRows<'_>| {
        let first = task * SPRING_ROWS_PER_TASK;
        kernels::spring_forces(isa, springs, Positions::new(current, points), first, out);
    };
    match spring_forces {
        SpringForces::Axes(axes) => {
            let [x, y, z] = axes.axes_mut();
            x[..rows]
                .par_chunks_mut(SPRING_ROWS_PER_TASK)
                .zip(y[..rows].par_chunks_mut(SPRING_ROWS_PER_TASK))
                .zip(z[..rows].par_chunks_mut(SPRING_ROWS_PER_TASK))
                .enumerate()
                .for_each(|(task, ((x, y), z))| pass(task, ForceRows::Axes([x, y, z])));
        }
        SpringForces::Points(out) => out[..rows]
            .par_chunks_mut(SPRING_ROWS_PER_TASK)
            .enumerate()
            .for_each(|(task, out)| pass(task, ForceRows::Points(out))),
    }
}

/// The self-collision resolver of a solver for `model` whose vertices are numbered as
/// `numbering`: grouping them as the scene placed them (or along the surface, where it placed
/// them in folds) only when `config` turns self-collision on.
fn resolver_for(
    model: &Model,
    numbering: &Numbering,
    config: Option<SelfCollision>,
) -> selfcollide::Resolver {
    match config {
        Some(_) => selfcollide::Resolver::grouped_by(model, &numbering.original),
        None => selfcollide::Resolver::default(),
    }
}

impl Solver for CpuSolver {
    fn describe(&self) -> String {
        let mut order = match self.numbering.order {
            VertexOrder::Mesh => String::new(),
            chosen => format!(", {}", chosen.name()),
        };
        if self.numbering.valence_windows {
            order += &format!(", valence-sorted in windows of {}", layout::VALENCE_WINDOW);
        }
        let depth = self.steps_per_sweep();
        if depth > 1 {
            // While nothing acts between steps (see `sweep`): a figure then depends on it.
            order += &format!(", up to {depth} steps per sweep");
        }
        format!(
            "cpu {} (f32, {} threads{order})",
            self.options.method.name(),
            self.threads()
        )
    }

    fn set_material(&mut self, material: &Material) -> Result<(), SimError> {
        let rebuild = material.stiffness_scale != self.material.stiffness_scale;
        self.material = *material;
        if rebuild {
            self.build_tables();
        }
        self.set_integrator();
        // Wind reads a triangle's velocity as its deltas over dt.
        self.set_external_forces();
        Ok(())
    }

    fn set_control(&mut self, control: &Control) -> Result<(), SimError> {
        self.control = control.clone();
        self.set_external_forces();
        collide::apply_pushes(
            &mut self.colliders,
            &self.model.collision.colliders,
            &control.ball_pushes,
        );
        Ok(())
    }

    fn set_self_collision(&mut self, config: Option<SelfCollision>) -> Result<(), SimError> {
        if self.self_collision.is_none() {
            self.self_collider = resolver_for(&self.model, &self.numbering, config);
        }
        self.self_collision = config;
        Ok(())
    }

    fn step_timed(&mut self) -> Result<(PhaseTimes, TimingSource), SimError> {
        let pool = std::sync::Arc::clone(&self.pool);
        let mut times = PhaseTimes::default();
        pool.install(|| self.step_once(Some(&mut times), false))?;
        Ok((times, TimingSource::WallClock))
    }

    fn step(&mut self, steps: u32) -> Result<(), SimError> {
        let pool = std::sync::Arc::clone(&self.pool);
        pool.install(|| {
            let mut left = steps as usize;
            while left > 0 {
                let depth = left.min(self.sweep_depth());
                if depth >= 2 && self.can_sweep() {
                    self.step_sweep(depth)?;
                    left -= depth;
                } else {
                    self.step_once(None, left > 1)?;
                    left -= 1;
                }
            }
            Ok(())
        })
    }

    fn read_state(&self) -> Result<State, SimError> {
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
        Ok(State {
            positions,
            previous_positions,
        })
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
        self.points_fresh = false;
    }

    fn steps_taken(&self) -> u64 {
        self.steps_taken
    }

    fn colliders(&self) -> Result<Vec<Collider>, SimError> {
        Ok(collide::placed(
            &self.colliders,
            self.steps_taken as f64 * self.material.dt,
        ))
    }

    fn broken_springs(&self) -> Result<Vec<u32>, SimError> {
        Ok(self.tears.list())
    }

    fn restore(&mut self, snapshot: &Snapshot) -> Result<(), SimError> {
        if self.tears.list() != snapshot.broken_springs {
            self.tears.restore(&snapshot.broken_springs)?;
            self.build_tables();
            self.set_external_forces();
        }
        self.write_state(&snapshot.state);
        collide::restore_balls(&mut self.colliders, &snapshot.colliders);
        self.steps_taken = snapshot.steps_taken;
        Ok(())
    }
}
