//! The GPU solver: the whole step in compute (and, for blending, render) passes, with the state
//! resident in GPU memory.
//!
//! [`GpuModel`] and [`GpuState`] own the buffers, each kernel in [`crate::kernels`] owns its
//! pipelines and bind groups, and the solver owns the kernels and the per-step scratch (the
//! per-vertex force buffers). Every pipeline is created by [`GpuSolver::new`] (self-collision:
//! by [`Solver::set_self_collision`]); a control or a material is written into buffers that
//! exist. The passes of one step are listed once, in [`GpuSolver::record_step`].

use std::sync::Arc;
use std::time::Duration;

use hooke_core::collide::{self, Collider};
use hooke_core::selfcollide::SelfCollision;
use hooke_core::tearing::{self, Tearing};
use hooke_core::{
    Control, Material, Model, PhaseTimes, SimError, Snapshot, Solver, State, TimingSource,
};

use crate::context::{GpuContext, GpuError};
use crate::gpu::{read_back, zeroed};
use crate::kernels::ScatterBuffers;
use crate::kernels::accumulate_atomic::AccumulateAtomic;
use crate::kernels::accumulate_blend::AccumulateBlend;
use crate::kernels::accumulate_incidence::{AccumulateIncidence, IncidenceLayout};
use crate::kernels::balls::Balls;
use crate::kernels::collide::Collide;
use crate::kernels::external::External;
use crate::kernels::force_springs::ForceSprings;
use crate::kernels::gather_integrate::GatherIntegrate;
use crate::kernels::handles::Handles;
use crate::kernels::integrate::Integrate;
use crate::kernels::self_collide::SelfCollidePass;
use crate::kernels::tear::{self, Tear};
use crate::layout::GpuStatus;
use crate::methods::{Accumulation, GpuMemory, GpuMethod};
use crate::model::{GpuModel, vec4s};
use crate::state::GpuState;
use crate::step::{
    Fused, PassSink, Phase, Record, TIMED_STEPS_PER_SUBMISSION, TIMESTAMP_SLOTS, Timestamped,
    WallClock, add_phase,
};

/// The force and integration passes: gather's one, or scatter's force pass, accumulation
/// (boxed: on wasm, wgpu's handles make it several times the size of the rest) and
/// integration.
enum Forces {
    Gather(GatherIntegrate),
    Scatter {
        /// The per-spring force pass, for the accumulations that read one force per spring
        /// (incidence, blend); the atomic ones compute the forces in their own pass.
        springs: Option<ForceSprings>,
        accumulation: Box<Accumulator>,
        integrate: Integrate,
    },
}

impl Forces {
    /// The passes of `model.method`, reading the model's stencil where it has one.
    fn new(
        ctx: &GpuContext,
        model: &GpuModel,
        state: &GpuState,
        extra_forces: &wgpu::Buffer,
    ) -> Result<Self, GpuError> {
        Ok(match model.method {
            GpuMethod::Gather => {
                Forces::Gather(GatherIntegrate::new(ctx, model, state, extra_forces)?)
            }
            GpuMethod::Scatter(accumulation) => {
                // Only incidence has a layout to choose (measured on the model's valences).
                let rows = match accumulation {
                    Accumulation::Incidence => match IncidenceLayout::for_model(&model.model) {
                        IncidenceLayout::Rows(width) => Some(width),
                        IncidenceLayout::Offsets => None,
                    },
                    _ => None,
                };
                match rows {
                    Some(width) => Self::incidence_rows(ctx, model, state, extra_forces, width)?,
                    None => Self::scatter(ctx, model, state, extra_forces, accumulation)?,
                }
            }
        })
    }

    /// Incidence over rows padded to `width` entries, summed in the integration pass (no
    /// per-vertex sums, see [`IncidenceLayout::Rows`]).
    fn incidence_rows(
        ctx: &GpuContext,
        model: &GpuModel,
        state: &GpuState,
        extra_forces: &wgpu::Buffer,
        width: u32,
    ) -> Result<Self, GpuError> {
        let springs = ForceSprings::new(ctx, model, state)?;
        let sums = (&springs.spring_forces, extra_forces);
        let (integrate, bytes) = Integrate::incidence_rows(ctx, model, state, sums, width)?;
        Ok(Forces::Scatter {
            springs: Some(springs),
            accumulation: Box::new(Accumulator::InIntegration { bytes }),
            integrate,
        })
    }

    /// Scatter with an accumulation into per-vertex sums, which the integration pass reads.
    fn scatter(
        ctx: &GpuContext,
        model: &GpuModel,
        state: &GpuState,
        extra_forces: &wgpu::Buffer,
        accumulation: Accumulation,
    ) -> Result<Self, GpuError> {
        let copy = wgpu::BufferUsages::COPY_SRC | wgpu::BufferUsages::COPY_DST;
        let forces = zeroed(
            ctx,
            "vertex forces",
            vec4s(model.model.vertex_count()),
            copy,
        );
        let buffers = ScatterBuffers::new(model, &forces, state)?;
        let fixed_point = accumulation == Accumulation::AtomicFixed;
        let (springs, accumulator) = match accumulation {
            Accumulation::AtomicF32 | Accumulation::AtomicFixed => {
                let sum = AccumulateAtomic::new(ctx, &buffers, state, fixed_point)?;
                (None, Accumulator::Atomic(sum))
            }
            Accumulation::Incidence => {
                let springs = ForceSprings::new(ctx, model, state)?;
                let sum =
                    AccumulateIncidence::new(ctx, &model.model, &buffers, &springs.spring_forces)?;
                (Some(springs), Accumulator::Incidence(sum))
            }
            Accumulation::BlendR32f | Accumulation::BlendR16f | Accumulation::BlendRgba8 => {
                let springs = ForceSprings::new(ctx, model, state)?;
                let sum =
                    AccumulateBlend::new(ctx, &buffers, &springs.spring_forces, accumulation)?;
                (Some(springs), Accumulator::Blend(sum))
            }
        };
        let own_sums = match &accumulator {
            Accumulator::Atomic(sum) => sum.own_sums(),
            _ => None,
        };
        let sums = (&forces, own_sums);
        let integrate = Integrate::new(ctx, model, state, sums, extra_forces, fixed_point)?;
        Ok(Forces::Scatter {
            springs,
            accumulation: Box::new(accumulator),
            integrate,
        })
    }
}

enum Accumulator {
    /// atomic-f32 or atomic-fixed: forces and sums in one pass.
    Atomic(AccumulateAtomic),
    Incidence(AccumulateIncidence),
    /// Incidence in padded rows, summed in the integration pass; the table's bytes.
    InIntegration {
        bytes: u64,
    },
    Blend(AccumulateBlend),
}

/// The GPU solver. Its state lives in GPU buffers; `read_state` copies it out.
pub struct GpuSolver {
    context: Arc<GpuContext>,
    model: GpuModel,
    state: GpuState,
    external: External,
    /// Per spring, 1 once torn: when springs can break or dampers must know (see `tear`).
    broken: Option<wgpu::Buffer>,
    /// Springs breaking (when the model tears, or a restored snapshot has torn springs).
    tear: Option<Tear>,
    force: Forces,
    collide: Option<Collide>,
    balls: Option<Balls>,
    handles: Option<Handles>,
    self_collide: Option<SelfCollidePass>,
    timestamps: Option<(wgpu::QuerySet, wgpu::Buffer)>,
    steps_taken: u64,
}

impl std::fmt::Debug for GpuSolver {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str(&self.describe())
    }
}

/// A failed batch: the simulation or the device.
enum RunError {
    Sim(SimError),
    Gpu(GpuError),
}

impl From<GpuError> for RunError {
    fn from(e: GpuError) -> Self {
        Self::Gpu(e)
    }
}

impl From<RunError> for SimError {
    fn from(e: RunError) -> Self {
        match e {
            RunError::Sim(e) => e,
            RunError::Gpu(e) => SimError::Device(e.to_string()),
        }
    }
}

fn device(error: GpuError) -> SimError {
    SimError::Device(error.to_string())
}

impl GpuSolver {
    /// Every buffer and pipeline of a step. The control starts empty ([`Solver::set_control`]).
    pub fn new(
        context: Arc<GpuContext>,
        model: &Model,
        material: &Material,
        method: GpuMethod,
    ) -> Result<Self, GpuError> {
        if let GpuMethod::Scatter(accumulation) = method
            && let Some((feature, name)) = accumulation.required_feature()
            && !context.has(feature)
        {
            return Err(GpuError::Unsupported {
                what: format!("scatter accumulation {}", accumulation.name()),
                feature: name,
                adapter: context.info.name.clone(),
            });
        }
        let ctx = &*context;
        let n = model.vertex_count();
        let gpu_model = GpuModel::new(ctx, model, material, method)?;
        let state = GpuState::new(ctx, n);
        // The flags exist when springs can break, or dampers must know which did.
        let broken = (model.tearing.is_some() || model.bending_damping > 0.0)
            .then(|| tear::broken_flags(ctx, model.spring_count()));
        let external = External::new(ctx, &gpu_model, &state, broken.as_ref())?;
        let extra_forces = &external.extra_forces;
        let force = Forces::new(ctx, &gpu_model, &state, extra_forces)?;
        let collide = Collide::new(ctx, &gpu_model, &state)?;
        let balls = match &collide {
            Some(collide) => Balls::new(ctx, &gpu_model, &state, collide)?,
            None => None,
        };
        let handles = Handles::new(ctx, &gpu_model, &state, collide.as_ref())?;
        let self_collide = match &model.collision.self_collision {
            Some(config) => Some(SelfCollidePass::new(ctx, &gpu_model, &state, config)?),
            None => None,
        };
        let tear = match (&model.tearing, &broken) {
            (Some(tearing), Some(broken)) => {
                Some(Tear::new(ctx, &gpu_model, &state, tearing, broken)?)
            }
            _ => None,
        };
        let timestamps = ctx.has(wgpu::Features::TIMESTAMP_QUERY).then(|| {
            let set = ctx.device.create_query_set(&wgpu::QuerySetDescriptor {
                label: Some("pass timestamps"),
                ty: wgpu::QueryType::Timestamp,
                count: TIMESTAMP_SLOTS * TIMED_STEPS_PER_SUBMISSION,
            });
            let resolved = ctx.device.create_buffer(&wgpu::BufferDescriptor {
                label: Some("resolved timestamps"),
                size: u64::from(TIMESTAMP_SLOTS * TIMED_STEPS_PER_SUBMISSION) * 8,
                usage: wgpu::BufferUsages::QUERY_RESOLVE | wgpu::BufferUsages::COPY_SRC,
                mapped_at_creation: false,
            });
            (set, resolved)
        });
        // The model's dampers act before any control is given.
        let mut gpu_model = gpu_model;
        gpu_model.uniforms.has_extra = u32::from(external.damps());
        gpu_model.write_uniforms(ctx);
        state.write(ctx, &State::at_rest(model.initial_positions.clone()));
        let solver = Self {
            broken,
            model: gpu_model,
            state,
            external,
            tear,
            force,
            collide,
            balls,
            handles,
            self_collide,
            timestamps,
            steps_taken: 0,
            context,
        };
        solver.context.take_error()?;
        Ok(solver)
    }

    pub fn method(&self) -> GpuMethod {
        self.model.method
    }

    /// Times phases with the wall clock even if the adapter has timestamp queries (the path
    /// taken on adapters without them).
    pub fn use_wall_clock_timing(&mut self) {
        self.timestamps = None;
    }

    pub fn context(&self) -> &Arc<GpuContext> {
        &self.context
    }

    /// The buffer holding the current positions (vec4 per vertex, `STORAGE | VERTEX`).
    pub fn current_positions(&self) -> &wgpu::Buffer {
        self.state.current_positions()
    }

    /// The per-spring broken flags (`u32`, 1 once broken) when springs can break: what a
    /// renderer binds to hide torn triangles.
    pub fn broken_springs_buffer(&self) -> Option<&wgpu::Buffer> {
        self.tear.as_ref().map(|t| &t.broken)
    }

    /// How many springs have broken (a `u32`, then padding to 16 bytes), for callers that read
    /// it back without waiting.
    pub fn broken_count_buffer(&self) -> Option<&wgpu::Buffer> {
        self.tear.as_ref().map(|t| &t.count)
    }

    pub fn memory(&self) -> GpuMemory {
        let n = self.model.model.vertex_count();
        let (topology, scratch) = match &self.force {
            Forces::Gather(_) => (0, 0),
            Forces::Scatter {
                springs,
                accumulation,
                ..
            } => {
                // Topology, scratch, and the per-vertex force sums (which the integration and
                // the accumulation's kernels hold) where there are any.
                let (topology, scratch, sums) = match accumulation.as_ref() {
                    // Over a stencil, the own springs' sums besides.
                    Accumulator::Atomic(a) => {
                        let own = a.own_sums().map_or(0, |_| vec4s(n));
                        (0, 0, vec4s(n) + own)
                    }
                    Accumulator::Incidence(a) => (a.bytes(), 0, vec4s(n)),
                    Accumulator::InIntegration { bytes } => (*bytes, 0, 0),
                    Accumulator::Blend(a) => (0, a.bytes(), vec4s(n)),
                };
                let spring_forces = springs.as_ref().map_or(0, ForceSprings::bytes);
                (topology, sums + spring_forces + scratch)
            }
        };
        GpuMemory {
            positions: self.state.bytes(),
            topology: self.model.topology_bytes + topology,
            // Integration scales; scatter's force sums, per-spring forces and accumulators.
            per_step: vec4s(n)
                + scratch
                + self.self_collide.as_ref().map_or(0, |p| p.bytes())
                + self.tear.as_ref().map_or(0, |t| t.bytes()),
            control: self.external.bytes()
                + self.model.triangle_bytes
                + self.collide.as_ref().map_or(0, |c| c.bytes())
                + self.handles.as_ref().map_or(0, |h| h.bytes()),
        }
    }

    /// The GPU work one step records: compute dispatches and draws (the blend accumulation's),
    /// as `hooke bench` reports them. Each pass but self-collision's is one dispatch or draw.
    pub fn dispatches_per_step(&self) -> u32 {
        struct Count(u32);
        impl PassSink for Count {
            fn pass(&mut self, _: Phase, _: &mut Record<'_>) -> Result<(), GpuError> {
                self.0 += 1;
                Ok(())
            }
        }
        let mut count = Count(0);
        // Counting records nothing and cannot fail.
        let _ = self.record_step(&mut count);
        let self_collision = self.self_collide.as_ref().map_or(0, |p| p.dispatches() - 1);
        count.0 + self_collision
    }

    /// Hands the passes of one step to `sink`, in order: tearing (when the model tears), the
    /// control's forces (when it has any), the force pass, the accumulation (scatter), integration, collision. The
    /// only place that lists them. (The step counts itself in integration: see `GpuStatus`.)
    fn record_step(&self, sink: &mut dyn PassSink) -> Result<(), GpuError> {
        let current = self.state.current;
        if let Some(tear) = &self.tear {
            sink.pass(Phase::Force, &mut |e, t| tear.kernel.encode(e, current, t))?;
        }
        if self.model.uniforms.has_extra != 0 {
            let external = &self.external;
            if external.wind_on() {
                sink.pass(Phase::External, &mut |e, t| {
                    external.wind.encode(e, current, t)
                })?;
            }
            sink.pass(Phase::External, &mut |e, t| {
                external.vertices.encode(e, current, t);
            })?;
        }
        match &self.force {
            Forces::Gather(gather) => {
                // Forces and integration in one pass, timed as the force phase.
                sink.pass(Phase::Force, &mut |e, t| {
                    gather.kernel.encode(e, current, t)
                })?;
            }
            Forces::Scatter {
                springs,
                accumulation,
                integrate,
            } => {
                if let Some(springs) = springs {
                    sink.pass(Phase::Force, &mut |e, t| {
                        springs.kernel.encode(e, current, t);
                    })?;
                }
                let acc = Phase::Accumulation;
                match accumulation.as_ref() {
                    // Forces computed as they are summed: one pass, timed as the force phase
                    // (as gather's).
                    Accumulator::Atomic(a) => {
                        sink.pass(Phase::Force, &mut |e, t| a.encode(e, current, t))?;
                    }
                    Accumulator::Incidence(a) => {
                        sink.pass(acc, &mut |e, t| a.kernel.encode(e, current, t))?;
                    }
                    // Summed as each vertex is integrated, timed as integration.
                    Accumulator::InIntegration { .. } => {}
                    Accumulator::Blend(a) => {
                        sink.pass(acc, &mut |e, t| a.encode_draw(e, t))?;
                        sink.pass(acc, &mut |e, t| a.encode_resolve(e, t))?;
                    }
                }
                sink.pass(Phase::Integration, &mut |e, t| {
                    integrate.kernel.encode(e, current, t);
                })?;
            }
        }
        if let Some(collide) = &self.collide {
            let balls = self.balls.as_ref();
            sink.pass(Phase::Collision, &mut |e, t| {
                collide.encode(e, current, balls, t);
            })?;
        }
        if let Some(handles) = &self.handles {
            sink.pass(Phase::Collision, &mut |e, t| {
                handles.kernel.encode(e, current, t);
            })?;
        }
        if let Some(pass) = &self.self_collide {
            sink.pass(Phase::Collision, &mut |e, t| pass.encode(e, current, t))?;
        }
        Ok(())
    }

    /// Records `steps` steps into `encoder`, for a frame that also draws: simulation passes,
    /// then the caller's render pass, in one submission. Nothing is read back; call
    /// [`GpuSolver::check`] when a verdict is needed.
    pub fn encode_steps(&mut self, encoder: &mut wgpu::CommandEncoder, steps: u32) {
        for _ in 0..steps {
            // Recording into one encoder cannot fail.
            let groups = self.context.records_debug_groups();
            if let Err(error) = self.record_step(&mut Fused { encoder, groups }) {
                self.context.report(error.to_string());
            }
            self.state.advance();
        }
        self.steps_taken += u64::from(steps);
    }

    /// Waits for submitted work and reports a non-finite position, an accumulator overflow or
    /// a device error since the solver started.
    pub fn check(&mut self) -> Result<(), SimError> {
        Ok(self.check_status()?)
    }

    /// Runs `steps` steps in one submission and checks the status once at the end.
    fn run_steps(&mut self, steps: u32) -> Result<(), RunError> {
        let mut encoder =
            self.context
                .device
                .create_command_encoder(&wgpu::CommandEncoderDescriptor {
                    label: Some("steps"),
                });
        for _ in 0..steps {
            self.record_step(&mut Fused {
                encoder: &mut encoder,
                groups: self.context.records_debug_groups(),
            })?;
            self.state.advance();
        }
        self.context.queue.submit([encoder.finish()]);
        self.steps_taken += u64::from(steps);
        self.check_status()
    }

    /// The status buffer ([`crate::layout::GpuStatus`]), for callers that read it back without
    /// waiting (see
    /// [`GpuSolver::judge_status`]).
    pub fn status_buffer(&self) -> &wgpu::Buffer {
        &self.state.status
    }

    /// Interprets status bytes read back from [`GpuSolver::status_buffer`].
    pub fn judge_status(&mut self, bytes: &[u8]) -> Result<(), SimError> {
        Ok(self.judge(bytes)?)
    }

    fn check_status(&mut self) -> Result<(), RunError> {
        let bytes = read_back(
            &self.context,
            &[(&self.state.status, std::mem::size_of::<GpuStatus>() as u64)],
        )?;
        self.judge(&bytes[0])
    }

    fn judge(&mut self, bytes: &[u8]) -> Result<(), RunError> {
        self.context.take_error()?;
        let status: GpuStatus = bytemuck::pod_read_unaligned(bytes);
        if status.first_bad_step != GpuStatus::NO_FAILURE {
            self.steps_taken = u64::from(status.first_bad_step);
            let bad = status.first_bad_vertex;
            return Err(RunError::Sim(if bad & GpuStatus::BALL_MARK != 0 {
                SimError::BallNonFinite {
                    step: self.steps_taken,
                    collider: (bad & !GpuStatus::BALL_MARK) as usize,
                }
            } else {
                SimError::NonFinite {
                    step: self.steps_taken,
                    vertex: bad as usize,
                }
            }));
        }
        if status.fixed_overflow != 0 {
            let uniforms = &self.model.uniforms;
            return Err(RunError::Sim(SimError::Overflow {
                step: self.steps_taken,
                detail: format!(
                    "a spring force exceeded the fixed-point range ({:.3e} N) and was clamped; use another accumulation",
                    f64::from(uniforms.fixed_limit) / f64::from(uniforms.fixed_scale)
                ),
            }));
        }
        Ok(())
    }

    /// `steps` steps with each phase timed: by GPU timestamps, the steps recorded back to back
    /// up to [`TIMED_STEPS_PER_SUBMISSION`] to a submission, or by the wall clock when the
    /// adapter has no timestamps (each pass then submitted alone and waited for). The same
    /// passes as every other step.
    fn run_timed_steps(&mut self, steps: u32) -> Result<(Vec<PhaseTimes>, TimingSource), RunError> {
        let untimed = PhaseTimes {
            force_accumulation: self.accumulates_separately().then_some(Duration::ZERO),
            ..Default::default()
        };
        let mut times = Vec::with_capacity(steps as usize);
        // Handles (reference-counted), so that the status can be checked between submissions.
        let Some((set, resolved)) = self.timestamps.clone() else {
            for _ in 0..steps {
                let mut sink = WallClock {
                    context: &self.context,
                    times: untimed,
                };
                self.record_step(&mut sink)?;
                times.push(sink.times);
                self.state.advance();
                self.steps_taken += 1;
                self.check_status()?;
            }
            return Ok((times, TimingSource::WallClock));
        };
        let period = f64::from(self.context.queue.get_timestamp_period());
        let mut left = steps;
        while left > 0 {
            let batch = left.min(TIMED_STEPS_PER_SUBMISSION);
            let mut encoder = self
                .context
                .device
                .create_command_encoder(&Default::default());
            let mut phases_of_steps = Vec::with_capacity(batch as usize);
            let mut used = 0;
            for _ in 0..batch {
                let mut sink = Timestamped {
                    encoder: &mut encoder,
                    groups: self.context.records_debug_groups(),
                    query_set: &set,
                    first: used,
                    phases: Vec::new(),
                };
                self.record_step(&mut sink)?;
                used += 2 * sink.phases.len() as u32;
                phases_of_steps.push(sink.phases);
                self.state.advance();
            }
            encoder.resolve_query_set(&set, 0..used, &resolved, 0);
            self.context.queue.submit([encoder.finish()]);
            self.steps_taken += u64::from(batch);
            let bytes = read_back(&self.context, &[(&resolved, u64::from(used) * 8)])?;
            let ticks: Vec<u64> = bytemuck::pod_collect_to_vec(&bytes[0]);
            let mut pairs = ticks.chunks_exact(2);
            for phases in phases_of_steps {
                let mut step = untimed;
                for (phase, pair) in phases.into_iter().zip(&mut pairs) {
                    let nanos = pair[1].saturating_sub(pair[0]) as f64 * period;
                    add_phase(&mut step, phase, Duration::from_secs_f64(nanos * 1e-9));
                }
                times.push(step);
            }
            self.check_status()?;
            left -= batch;
        }
        Ok((times, TimingSource::Timestamps))
    }

    /// Records, into `encoder`, copies of the sphere colliders' current places (centre, radius)
    /// into `target`, one `vec4` per sphere in collider order: how a renderer draws dynamic
    /// balls without reading them back.
    pub fn copy_spheres(&self, encoder: &mut wgpu::CommandEncoder, target: &wgpu::Buffer) {
        if let Some(collide) = &self.collide {
            collide.copy_spheres(encoder, target);
        }
    }

    /// Whether the per-vertex sums take passes of their own, timed as the accumulation phase:
    /// gather sums as it computes, as do the atomic accumulations, and incidence in padded
    /// rows sums in the integration pass.
    pub fn accumulates_separately(&self) -> bool {
        match &self.force {
            Forces::Gather(_) => false,
            Forces::Scatter { accumulation, .. } => matches!(
                accumulation.as_ref(),
                Accumulator::Incidence(_) | Accumulator::Blend(_)
            ),
        }
    }

    /// Up to this many steps go into one command buffer.
    const STEPS_PER_SUBMISSION: u32 = 256;
}

impl Solver for GpuSolver {
    fn describe(&self) -> String {
        let springs = match &self.force {
            Forces::Gather(gather) => format!("{}, ", gather.variant.name()),
            Forces::Scatter { accumulation, .. } => match accumulation.as_ref() {
                Accumulator::Atomic(sum) if sum.reads_stencil => "stencil, ".to_owned(),
                Accumulator::InIntegration { .. } => "rows, ".to_owned(),
                _ => String::new(),
            },
        };
        format!(
            "gpu {} (f32, {springs}{})",
            self.model.method.name(),
            self.context.info.name
        )
    }

    fn set_material(&mut self, material: &Material) -> Result<(), SimError> {
        self.model.set_material(&self.context, material);
        self.context.take_error().map_err(device)
    }

    fn set_control(&mut self, control: &Control) -> Result<(), SimError> {
        let (has_extra, triangles) = self
            .external
            .write(&self.context, &self.model.model, control);
        self.model.uniforms.has_extra = u32::from(has_extra);
        self.model.uniforms.triangle_count = triangles;
        self.model.write_uniforms(&self.context);
        if let Some(collide) = &self.collide {
            collide.write_pushes(&self.context, &control.ball_pushes);
        }
        self.context.take_error().map_err(device)
    }

    fn set_self_collision(&mut self, config: Option<SelfCollision>) -> Result<(), SimError> {
        self.self_collide = match &config {
            Some(config) => Some(
                SelfCollidePass::new(&self.context, &self.model, &self.state, config)
                    .map_err(device)?,
            ),
            None => None,
        };
        self.context.take_error().map_err(device)
    }

    fn step(&mut self, steps: u32) -> Result<(), SimError> {
        let mut remaining = steps;
        while remaining > 0 {
            let batch = remaining.min(Self::STEPS_PER_SUBMISSION);
            self.run_steps(batch)?;
            remaining -= batch;
        }
        Ok(())
    }

    fn step_timed(&mut self) -> Result<(PhaseTimes, TimingSource), SimError> {
        let (mut times, source) = self.run_timed_steps(1)?;
        Ok((times.remove(0), source))
    }

    fn steps_timed(&mut self, steps: u32) -> Result<(Vec<PhaseTimes>, TimingSource), SimError> {
        Ok(self.run_timed_steps(steps)?)
    }

    fn read_state(&self) -> Result<State, SimError> {
        self.state.read(&self.context).map_err(device)
    }

    fn write_state(&mut self, state: &State) {
        self.state.write(&self.context, state);
    }

    fn steps_taken(&self) -> u64 {
        self.steps_taken
    }

    fn colliders(&self) -> Result<Vec<Collider>, SimError> {
        let t = self.steps_taken as f64 * self.model.material.dt;
        match &self.collide {
            Some(collide) => collide.read(&self.context, t).map_err(device),
            None => Ok(collide::placed(&self.model.model.collision.colliders, t)),
        }
    }

    fn broken_springs(&self) -> Result<Vec<u32>, SimError> {
        match &self.tear {
            Some(tear) => tear.read(&self.context).map_err(device),
            None => Ok(Vec::new()),
        }
    }

    fn restore(&mut self, snapshot: &Snapshot) -> Result<(), SimError> {
        let spring_count = self.model.model.spring_count();
        let broken = tearing::broken_flags(&snapshot.broken_springs, spring_count)?;
        if self.tear.is_none() && !snapshot.broken_springs.is_empty() {
            // A model that does not tear keeps a snapshot's tears: nothing more breaks.
            let never = Tearing {
                max_stretch: f64::INFINITY,
            };
            let context = &self.context;
            // The tears' zero stiffness goes into the records, which the gather must then read.
            self.model.let_records_change(context).map_err(device)?;
            let flags = self
                .broken
                .get_or_insert_with(|| tear::broken_flags(context, spring_count));
            let tear = Tear::new(context, &self.model, &self.state, &never, flags);
            self.tear = Some(tear.map_err(device)?);
            // Kernels that read a stencil or one stiffness now read the records.
            let extra = &self.external.extra_forces;
            self.force = Forces::new(context, &self.model, &self.state, extra).map_err(device)?;
        }
        if let Some(tear) = &self.tear {
            tear.write(&self.context, &broken);
            self.model.write_force_records(&self.context, &broken);
        }
        self.state.write(&self.context, &snapshot.state);
        if let Some(collide) = &self.collide {
            collide.restore_balls(&self.context, &snapshot.colliders);
        }
        self.steps_taken = snapshot.steps_taken;
        self.state.reset_status(&self.context, snapshot.steps_taken);
        self.context.take_error().map_err(device)
    }
}
