//! The GPU solver: the whole step in compute (and, for blending, render) passes, with the state
//! resident in GPU memory.
//!
//! A step is: external forces (only when the scene has point forces, drags or wind), the force
//! pass (gather: per-vertex sum; scatter: one force per spring), the accumulation (scatter only,
//! in one of six ways), then one integration pass shared by every method, and a 1-invocation
//! tick that counts steps. Positions ping-pong between two buffers created with
//! `STORAGE | VERTEX` usage, so a renderer can draw the current one directly.

use std::sync::Arc;
use std::time::{Duration, Instant};

use glam::DVec3;
use hooke_core::collide::{Collider, MAX_KEYFRAMES, Shape};
use hooke_core::{Model, PhaseTimes, SimError, SimParams, Solver, State};

use crate::context::{GpuContext, GpuError};
use crate::gpu::{self, bind_group, compute_pipeline, dispatch, read_back, storage, zeroed};
use crate::kernels;
use crate::layout::{GatherEntry, GpuSpring, GpuStatus, StepUniforms};
use crate::self_collide::{SelfCollidePass, SolverBuffers};

/// How scatter (ECA) sums the spring forces at the vertices.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum Accumulation {
    /// Float atomics (needs SHADER_FLOAT32_ATOMIC); summation order varies from run to run.
    AtomicF32,
    /// Integer atomics on fixed-point values; deterministic, works on WebGPU.
    AtomicFixed,
    /// Each vertex gathers its springs' forces; deterministic, no atomics.
    Incidence,
    /// The paper's path: point primitives blended into a 32-bit float target.
    BlendR32f,
    /// ... into a 16-bit float target.
    BlendR16f,
    /// ... into two 8-bit fixed-point targets (positive and negative parts), as the paper had to.
    BlendRgba8,
}

impl Accumulation {
    pub const ALL: [Accumulation; 6] = [
        Self::AtomicF32,
        Self::AtomicFixed,
        Self::Incidence,
        Self::BlendR32f,
        Self::BlendR16f,
        Self::BlendRgba8,
    ];

    pub fn name(self) -> &'static str {
        match self {
            Self::AtomicF32 => "atomic-f32",
            Self::AtomicFixed => "atomic-fixed",
            Self::Incidence => "incidence",
            Self::BlendR32f => "blend-r32f",
            Self::BlendR16f => "blend-r16f",
            Self::BlendRgba8 => "blend-rgba8",
        }
    }

    /// Whether results are bit-identical from run to run by construction. (Blending happens in
    /// primitive order, so the blend paths are deterministic on conforming hardware too; the
    /// tests check it rather than promise it.)
    pub fn is_deterministic(self) -> bool {
        matches!(self, Self::AtomicFixed | Self::Incidence)
    }

    fn required_feature(self) -> Option<(wgpu::Features, &'static str)> {
        match self {
            Self::AtomicF32 => Some((
                wgpu::Features::SHADER_FLOAT32_ATOMIC,
                "SHADER_FLOAT32_ATOMIC",
            )),
            Self::BlendR32f => Some((wgpu::Features::FLOAT32_BLENDABLE, "FLOAT32_BLENDABLE")),
            _ => None,
        }
    }

    fn blend_format(self) -> Option<wgpu::TextureFormat> {
        match self {
            Self::BlendR32f => Some(wgpu::TextureFormat::Rgba32Float),
            Self::BlendR16f => Some(wgpu::TextureFormat::Rgba16Float),
            Self::BlendRgba8 => Some(wgpu::TextureFormat::Rgba8Unorm),
            _ => None,
        }
    }
}

/// Which of the paper's data structures the GPU solver uses.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum GpuMethod {
    /// Point-centric (PCA): per-vertex sums over a CSR adjacency in valence-sorted order.
    Gather,
    /// Edge-centric (ECA): one force per spring, then an accumulation.
    Scatter(Accumulation),
}

impl GpuMethod {
    /// Every method, gather first.
    pub fn all() -> Vec<GpuMethod> {
        std::iter::once(Self::Gather)
            .chain(Accumulation::ALL.map(Self::Scatter))
            .collect()
    }

    /// `"gather"` or `"scatter/<accumulation>"`.
    pub fn name(self) -> String {
        match self {
            Self::Gather => "gather".to_owned(),
            Self::Scatter(a) => format!("scatter/{}", a.name()),
        }
    }

    pub fn is_deterministic(self) -> bool {
        match self {
            Self::Gather => true,
            Self::Scatter(a) => a.is_deterministic(),
        }
    }
}

/// Where per-phase times come from.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum TimingSource {
    /// GPU timestamp queries around each pass.
    Timestamps,
    /// Wall clock around each phase submitted alone and waited for (no TIMESTAMP_QUERY).
    WallClock,
}

/// Bytes of GPU memory by role (the paper's Table 1 from the real allocations).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct GpuMemory {
    /// Two position buffers and the deltas.
    pub positions: u64,
    /// Adjacency (gather) or springs and accumulation structures (scatter).
    pub topology: u64,
    /// Per-vertex forces and integration constants, per-spring forces, accumulators, targets.
    pub per_step: u64,
}

impl GpuMemory {
    pub fn total(&self) -> u64 {
        self.positions + self.topology + self.per_step
    }
}

/// A spring stretched to twice its rest length: the force scale fixed-point and 8-bit
/// accumulation are sized for (`max D l0`). Larger forces are clamped (fixed point: and
/// reported) or saturate (8-bit blending, as in the paper).
fn force_range(model: &Model) -> f64 {
    model
        .stiffnesses
        .iter()
        .zip(&model.rest_lengths)
        .map(|(k, l)| k * l)
        .fold(0.0, f64::max)
        .max(f64::MIN_POSITIVE)
}

/// Texels per row of the blend force target.
const BLEND_WIDTH: u32 = 2048;

enum Phase {
    External,
    Force,
    Accumulation,
    Integration,
    Collision,
}

/// Static data of the force and accumulation passes.
enum Topology {
    Gather {
        pipeline: wgpu::ComputePipeline,
        /// Indexed by which position buffer is current.
        bind_groups: [wgpu::BindGroup; 2],
    },
    Scatter {
        springs_pipeline: wgpu::ComputePipeline,
        springs_bind_groups: [wgpu::BindGroup; 2],
        accumulation: AccumulationPass,
    },
}

enum AccumulationPass {
    AtomicF32 {
        pipeline: wgpu::ComputePipeline,
        bind_group: wgpu::BindGroup,
    },
    Fixed {
        accumulate: wgpu::ComputePipeline,
        accumulate_group: wgpu::BindGroup,
        resolve: wgpu::ComputePipeline,
        resolve_group: wgpu::BindGroup,
        accumulators: wgpu::Buffer,
    },
    Incidence {
        pipeline: wgpu::ComputePipeline,
        bind_group: wgpu::BindGroup,
    },
    Blend {
        pipeline: wgpu::RenderPipeline,
        bind_group: wgpu::BindGroup,
        targets: Vec<wgpu::TextureView>,
        resolve: wgpu::ComputePipeline,
        resolve_group: wgpu::BindGroup,
    },
}

/// Colliders on the GPU: four `vec4` per collider (see collide.wgsl), the collide kernel, and
/// for dynamic balls the kernels that move them.
struct CollidePass {
    pipeline: wgpu::ComputePipeline,
    /// By current position buffer.
    groups: [wgpu::BindGroup; 2],
    colliders: wgpu::Buffer,
    /// Colliders in `colliders`.
    count: u32,
    keyframes: wgpu::Buffer,
    balls: Option<BallsPass>,
}

struct BallsPass {
    advance: wgpu::ComputePipeline,
    advance_group: wgpu::BindGroup,
    contacts: wgpu::ComputePipeline,
    contacts_group: wgpu::BindGroup,
}

impl CollidePass {
    fn encode(
        &self,
        encoder: &mut wgpu::CommandEncoder,
        current: usize,
        vertices: u32,
        timestamp_writes: Option<wgpu::ComputePassTimestampWrites<'_>>,
    ) {
        let mut pass = encoder.begin_compute_pass(&wgpu::ComputePassDescriptor {
            label: Some("collide"),
            timestamp_writes,
        });
        gpu::dispatch_in(&mut pass, &self.pipeline, &self.groups[current], vertices);
        if let Some(balls) = &self.balls {
            // One workgroup per collider.
            let colliders = self.count;
            gpu::dispatch_in(
                &mut pass,
                &balls.advance,
                &balls.advance_group,
                colliders * gpu::WORKGROUP_SIZE,
            );
            pass.set_pipeline(&balls.contacts);
            pass.set_bind_group(0, &balls.contacts_group, &[]);
            pass.dispatch_workgroups(1, 1, 1);
        }
    }
}

struct ExternalPass {
    wind: Option<(wgpu::ComputePipeline, [wgpu::BindGroup; 2])>,
    vertices: wgpu::ComputePipeline,
    vertex_groups: [wgpu::BindGroup; 2],
    bytes: u64,
}

/// The GPU solver. Its state lives in GPU buffers; `read_state` copies it out.
pub struct GpuSolver {
    context: Arc<GpuContext>,
    method: GpuMethod,
    model: Model,
    uniforms: StepUniforms,
    uniform_buffer: wgpu::Buffer,
    positions: [wgpu::Buffer; 2],
    current: usize,
    deltas: wgpu::Buffer,
    scales: wgpu::Buffer,
    forces: wgpu::Buffer,
    extra_forces: wgpu::Buffer,
    status: wgpu::Buffer,
    topology: Topology,
    topology_bytes: u64,
    per_step_bytes: u64,
    integrate: wgpu::ComputePipeline,
    integrate_groups: [wgpu::BindGroup; 2],
    tick: wgpu::ComputePipeline,
    tick_group: wgpu::BindGroup,
    external: Option<ExternalPass>,
    /// The collision pass, when the scene has colliders.
    collide: Option<CollidePass>,
    /// The colliders' settings as last given (dynamic balls' places live on the GPU).
    collider_settings: Vec<Collider>,
    /// The time step, s.
    dt: f64,
    self_collide: Option<SelfCollidePass>,
    timestamps: Option<(wgpu::QuerySet, wgpu::Buffer)>,
    steps_taken: u64,
}

impl std::fmt::Debug for GpuSolver {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str(&self.describe())
    }
}

const VEC4: u64 = 16;
/// Timestamp slots: two per pass, at most 8 passes per step.
const TIMESTAMP_SLOTS: u32 = 16;

fn vec4s(count: usize) -> u64 {
    count as u64 * VEC4
}

impl GpuSolver {
    pub fn new(
        context: Arc<GpuContext>,
        model: &Model,
        params: &SimParams,
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
        let n = model.vertex_count();
        gpu::check_binding_size(&context, "positions", vec4s(n))?;
        gpu::check_binding_size(&context, "spring forces", vec4s(model.spring_count()))?;
        let ctx = &*context;
        let copy = wgpu::BufferUsages::COPY_SRC | wgpu::BufferUsages::COPY_DST;
        let uniforms = StepUniforms {
            vertex_count: n as u32,
            spring_count: model.spring_count() as u32,
            ..Default::default()
        };
        let uniform_buffer = ctx.device.create_buffer(&wgpu::BufferDescriptor {
            label: Some("step uniforms"),
            size: std::mem::size_of::<StepUniforms>() as u64,
            usage: wgpu::BufferUsages::UNIFORM | wgpu::BufferUsages::COPY_DST,
            mapped_at_creation: false,
        });
        let positions = [0, 1].map(|k| {
            zeroed(
                ctx,
                &format!("positions {k}"),
                vec4s(n),
                copy | wgpu::BufferUsages::VERTEX,
            )
        });
        let deltas = zeroed(ctx, "deltas", vec4s(n), copy);
        let scales = zeroed(ctx, "integration scales", vec4s(n), copy);
        let forces = zeroed(ctx, "vertex forces", vec4s(n), copy);
        let extra_forces = zeroed(ctx, "extra forces", vec4s(n), copy);
        let status = storage(ctx, "status", &[GpuStatus::fresh(0)], copy);

        let (topology, topology_bytes, accumulation_bytes) = build_topology(
            ctx,
            model,
            method,
            &uniform_buffer,
            &positions,
            &forces,
            &status,
        )?;
        let integrate = compute_pipeline(ctx, "integrate", kernels::INTEGRATE, "main")?;
        let integrate_layout = integrate.get_bind_group_layout(0);
        let integrate_groups = [0, 1].map(|current| {
            bind_group(
                ctx,
                "integrate",
                &integrate_layout,
                &[
                    (0, uniform_buffer.as_entire_binding()),
                    (1, positions[current].as_entire_binding()),
                    (2, positions[1 - current].as_entire_binding()),
                    (3, deltas.as_entire_binding()),
                    (4, scales.as_entire_binding()),
                    (5, forces.as_entire_binding()),
                    (6, extra_forces.as_entire_binding()),
                    (7, status.as_entire_binding()),
                ],
            )
        });
        let tick = compute_pipeline(ctx, "tick", kernels::TICK, "main")?;
        let tick_group = bind_group(
            ctx,
            "tick",
            &tick.get_bind_group_layout(0),
            &[(0, status.as_entire_binding())],
        );
        let timestamps = ctx.has(wgpu::Features::TIMESTAMP_QUERY).then(|| {
            let set = ctx.device.create_query_set(&wgpu::QuerySetDescriptor {
                label: Some("pass timestamps"),
                ty: wgpu::QueryType::Timestamp,
                count: TIMESTAMP_SLOTS,
            });
            let resolved = ctx.device.create_buffer(&wgpu::BufferDescriptor {
                label: Some("resolved timestamps"),
                size: u64::from(TIMESTAMP_SLOTS) * 8,
                usage: wgpu::BufferUsages::QUERY_RESOLVE | wgpu::BufferUsages::COPY_SRC,
                mapped_at_creation: false,
            });
            (set, resolved)
        });
        let mut solver = Self {
            per_step_bytes: 2 * vec4s(n) + accumulation_bytes,
            context,
            method,
            model: model.clone(),
            uniforms,
            uniform_buffer,
            positions,
            current: 0,
            deltas,
            scales,
            forces,
            extra_forces,
            status,
            topology,
            topology_bytes,
            integrate,
            integrate_groups,
            tick,
            tick_group,
            external: None,
            collide: None,
            collider_settings: Vec::new(),
            dt: params.dt,
            self_collide: None,
            timestamps,
            steps_taken: 0,
        };
        solver.configure_accumulation_scales();
        solver.set_params(params);
        solver.write_state(&State::at_rest(model.initial_positions.clone()));
        solver.context.take_error()?;
        Ok(solver)
    }

    pub fn method(&self) -> GpuMethod {
        self.method
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
        &self.positions[self.current]
    }

    pub fn memory(&self) -> GpuMemory {
        let n = self.model.vertex_count();
        GpuMemory {
            positions: 3 * vec4s(n),
            topology: self.topology_bytes,
            per_step: self.per_step_bytes
                + self.external.as_ref().map_or(0, |e| e.bytes)
                + self.self_collide.as_ref().map_or(0, |p| p.bytes()),
        }
    }

    fn configure_accumulation_scales(&mut self) {
        let range = force_range(&self.model);
        let max_valence = (0..self.model.vertex_count())
            .map(|v| self.model.adjacency.valence(v))
            .max()
            .unwrap_or(0);
        // A vertex sums at most max_valence contributions, each within the limit: no wrap.
        let limit = (2f64.powi(31) / f64::from(max_valence + 1)).floor() - 256.0;
        self.uniforms.fixed_limit = limit as f32;
        self.uniforms.fixed_scale = (limit / range) as f32;
        let n = self.model.vertex_count() as u32;
        self.uniforms.blend_width = BLEND_WIDTH.min(n.max(1));
        self.uniforms.blend_height = n.div_ceil(self.uniforms.blend_width).max(1);
        // Float targets: a power of two near the range (exact rescaling). 8-bit targets: the
        // range times the valence, so a vertex's sum of either sign stays below 1.
        self.uniforms.blend_scale = match self.method {
            GpuMethod::Scatter(Accumulation::BlendRgba8) => {
                (range * f64::from(max_valence.max(1))) as f32
            }
            _ => 2f64.powi(range.log2().round() as i32) as f32,
        };
    }

    fn write_uniforms(&self) {
        self.context.queue.write_buffer(
            &self.uniform_buffer,
            0,
            bytemuck::bytes_of(&self.uniforms),
        );
    }

    /// Records one step into `encoder`; `timer` gets a slot pair per pass when timing.
    fn encode_step(&self, encoder: &mut wgpu::CommandEncoder, timer: &mut Option<PassTimer<'_>>) {
        let n = self.model.vertex_count() as u32;
        let current = self.current;
        if let Some(external) = &self.external {
            if let Some((pipeline, groups)) = &external.wind {
                let writes = PassTimer::next(timer, Phase::External);
                dispatch(
                    encoder,
                    "wind per triangle",
                    pipeline,
                    &groups[current],
                    self.uniforms.triangle_count,
                    writes,
                );
            }
            let writes = PassTimer::next(timer, Phase::External);
            dispatch(
                encoder,
                "external forces",
                &external.vertices,
                &external.vertex_groups[current],
                n,
                writes,
            );
        }
        match &self.topology {
            Topology::Gather {
                pipeline,
                bind_groups,
            } => {
                let writes = PassTimer::next(timer, Phase::Force);
                dispatch(
                    encoder,
                    "gather forces",
                    pipeline,
                    &bind_groups[current],
                    n,
                    writes,
                );
            }
            Topology::Scatter {
                springs_pipeline,
                springs_bind_groups,
                accumulation,
            } => {
                let springs = self.uniforms.spring_count;
                let writes = PassTimer::next(timer, Phase::Force);
                dispatch(
                    encoder,
                    "spring forces",
                    springs_pipeline,
                    &springs_bind_groups[current],
                    springs,
                    writes,
                );
                self.encode_accumulation(encoder, accumulation, timer);
            }
        }
        let writes = PassTimer::next(timer, Phase::Integration);
        dispatch(
            encoder,
            "integrate",
            &self.integrate,
            &self.integrate_groups[current],
            n,
            writes,
        );
        if let Some(pass) = &self.collide {
            pass.encode(
                encoder,
                current,
                n,
                PassTimer::next(timer, Phase::Collision),
            );
        }
        if let Some(pass) = &self.self_collide {
            pass.encode(encoder, current, PassTimer::next(timer, Phase::Collision));
        }
        dispatch(encoder, "tick", &self.tick, &self.tick_group, 1, None);
    }

    fn encode_accumulation(
        &self,
        encoder: &mut wgpu::CommandEncoder,
        accumulation: &AccumulationPass,
        timer: &mut Option<PassTimer<'_>>,
    ) {
        let n = self.model.vertex_count() as u32;
        let springs = self.uniforms.spring_count;
        match accumulation {
            AccumulationPass::AtomicF32 {
                pipeline,
                bind_group,
            } => {
                encoder.clear_buffer(&self.forces, 0, None);
                let writes = PassTimer::next(timer, Phase::Accumulation);
                dispatch(
                    encoder,
                    "accumulate atomic-f32",
                    pipeline,
                    bind_group,
                    springs,
                    writes,
                );
            }
            AccumulationPass::Fixed {
                accumulate,
                accumulate_group,
                resolve,
                resolve_group,
                accumulators,
            } => {
                encoder.clear_buffer(accumulators, 0, None);
                let writes = PassTimer::next(timer, Phase::Accumulation);
                dispatch(
                    encoder,
                    "accumulate atomic-fixed",
                    accumulate,
                    accumulate_group,
                    springs,
                    writes,
                );
                let writes = PassTimer::next(timer, Phase::Accumulation);
                dispatch(
                    encoder,
                    "resolve atomic-fixed",
                    resolve,
                    resolve_group,
                    n,
                    writes,
                );
            }
            AccumulationPass::Incidence {
                pipeline,
                bind_group,
            } => {
                let writes = PassTimer::next(timer, Phase::Accumulation);
                dispatch(
                    encoder,
                    "accumulate incidence",
                    pipeline,
                    bind_group,
                    n,
                    writes,
                );
            }
            AccumulationPass::Blend {
                pipeline,
                bind_group,
                targets,
                resolve,
                resolve_group,
            } => {
                let attachments: Vec<Option<wgpu::RenderPassColorAttachment<'_>>> = targets
                    .iter()
                    .map(|view| {
                        Some(wgpu::RenderPassColorAttachment {
                            view,
                            depth_slice: None,
                            resolve_target: None,
                            ops: wgpu::Operations {
                                load: wgpu::LoadOp::Clear(wgpu::Color::TRANSPARENT),
                                store: wgpu::StoreOp::Store,
                            },
                        })
                    })
                    .collect();
                let timestamp_writes = PassTimer::next(timer, Phase::Accumulation).map(|w| {
                    wgpu::RenderPassTimestampWrites {
                        query_set: w.query_set,
                        beginning_of_pass_write_index: w.beginning_of_pass_write_index,
                        end_of_pass_write_index: w.end_of_pass_write_index,
                    }
                });
                {
                    let mut pass = encoder.begin_render_pass(&wgpu::RenderPassDescriptor {
                        label: Some("accumulate blend"),
                        color_attachments: &attachments,
                        depth_stencil_attachment: None,
                        timestamp_writes,
                        occlusion_query_set: None,
                        multiview_mask: None,
                    });
                    pass.set_pipeline(pipeline);
                    pass.set_bind_group(0, bind_group, &[]);
                    pass.draw(0..2 * springs, 0..1);
                }
                let writes = PassTimer::next(timer, Phase::Accumulation);
                dispatch(encoder, "resolve blend", resolve, resolve_group, n, writes);
            }
        }
    }

    /// Records `steps` steps into `encoder`, for a frame that also draws: simulation passes,
    /// then the caller's render pass, in one submission. Nothing is read back; call
    /// [`GpuSolver::check`] when a verdict is needed.
    pub fn encode_steps(&mut self, encoder: &mut wgpu::CommandEncoder, steps: u32) {
        for _ in 0..steps {
            self.encode_step(encoder, &mut None);
            self.current = 1 - self.current;
        }
        self.steps_taken += u64::from(steps);
    }

    /// Waits for submitted work and reports a non-finite position, an accumulator overflow or
    /// a device error since the solver started.
    pub fn check(&mut self) -> Result<(), SimError> {
        self.check_status().map_err(|e| match e {
            RunError::Sim(e) => e,
            RunError::Gpu(e) => SimError::Device(e.to_string()),
        })
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
            self.encode_step(&mut encoder, &mut None);
            self.current = 1 - self.current;
        }
        self.context.queue.submit([encoder.finish()]);
        self.steps_taken += u64::from(steps);
        self.check_status()
    }

    /// The 16-byte status buffer, for callers that read it back without waiting (see
    /// [`GpuSolver::judge_status`]).
    pub fn status_buffer(&self) -> &wgpu::Buffer {
        &self.status
    }

    /// Interprets status bytes read back from [`GpuSolver::status_buffer`].
    pub fn judge_status(&mut self, bytes: &[u8]) -> Result<(), SimError> {
        self.judge(bytes).map_err(|e| match e {
            RunError::Sim(e) => e,
            RunError::Gpu(e) => SimError::Device(e.to_string()),
        })
    }

    fn check_status(&mut self) -> Result<(), RunError> {
        let bytes = read_back(
            &self.context,
            &[(&self.status, std::mem::size_of::<GpuStatus>() as u64)],
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
            return Err(RunError::Sim(SimError::Overflow {
                step: self.steps_taken,
                detail: format!(
                    "a spring force exceeded the fixed-point range ({:.3e} N) and was clamped; use another accumulation",
                    f64::from(self.uniforms.fixed_limit) / f64::from(self.uniforms.fixed_scale)
                ),
            }));
        }
        Ok(())
    }

    /// One step with each phase timed (GPU timestamps, or wall clock when the adapter has none).
    pub fn step_timed(&mut self) -> Result<(PhaseTimes, TimingSource), GpuError> {
        let times = match &self.timestamps {
            Some((set, resolved)) => {
                let mut encoder = self
                    .context
                    .device
                    .create_command_encoder(&Default::default());
                let mut timer = Some(PassTimer {
                    query_set: set,
                    phases: Vec::new(),
                });
                self.encode_step(&mut encoder, &mut timer);
                let phases = timer.map(|t| t.phases).unwrap_or_default();
                let used = 2 * phases.len() as u32;
                encoder.resolve_query_set(set, 0..used, resolved, 0);
                self.context.queue.submit([encoder.finish()]);
                let bytes = read_back(&self.context, &[(resolved, u64::from(used) * 8)])?;
                let ticks: Vec<u64> = bytemuck::pod_collect_to_vec(&bytes[0]);
                let period = f64::from(self.context.queue.get_timestamp_period());
                let mut times = self.empty_times();
                for (k, phase) in phases.iter().enumerate() {
                    let nanos = ticks[2 * k + 1].saturating_sub(ticks[2 * k]) as f64 * period;
                    add_phase(&mut times, phase, Duration::from_secs_f64(nanos * 1e-9));
                }
                (times, TimingSource::Timestamps)
            }
            None => (self.step_wall_clock()?, TimingSource::WallClock),
        };
        self.current = 1 - self.current;
        self.steps_taken += 1;
        self.check_status().map_err(RunError::into_gpu)?;
        Ok(times)
    }

    fn empty_times(&self) -> PhaseTimes {
        PhaseTimes {
            external: Duration::ZERO,
            force_calculation: Duration::ZERO,
            force_accumulation: matches!(self.method, GpuMethod::Scatter(_))
                .then_some(Duration::ZERO),
            integration: Duration::ZERO,
            collision: Duration::ZERO,
        }
    }

    /// Fallback timing: the step's passes submitted phase by phase, waiting after each.
    fn step_wall_clock(&self) -> Result<PhaseTimes, GpuError> {
        let mut times = self.empty_times();
        let wait = |start: Instant| -> Result<Duration, GpuError> {
            self.context
                .device
                .poll(wgpu::PollType::wait_indefinitely())
                .map_err(|e| GpuError::ReadBack(e.to_string()))?;
            Ok(start.elapsed())
        };
        let n = self.model.vertex_count() as u32;
        let current = self.current;
        let submit = |label: &str,
                      record: &dyn Fn(&mut wgpu::CommandEncoder)|
         -> Result<Duration, GpuError> {
            let mut encoder = self
                .context
                .device
                .create_command_encoder(&wgpu::CommandEncoderDescriptor { label: Some(label) });
            record(&mut encoder);
            let start = Instant::now();
            self.context.queue.submit([encoder.finish()]);
            wait(start)
        };
        if let Some(external) = &self.external {
            times.external = submit("external", &|e| {
                if let Some((pipeline, groups)) = &external.wind {
                    dispatch(
                        e,
                        "wind per triangle",
                        pipeline,
                        &groups[current],
                        self.uniforms.triangle_count,
                        None,
                    );
                }
                dispatch(
                    e,
                    "external forces",
                    &external.vertices,
                    &external.vertex_groups[current],
                    n,
                    None,
                );
            })?;
        }
        match &self.topology {
            Topology::Gather {
                pipeline,
                bind_groups,
            } => {
                times.force_calculation = submit("force", &|e| {
                    dispatch(e, "gather forces", pipeline, &bind_groups[current], n, None);
                })?;
            }
            Topology::Scatter {
                springs_pipeline,
                springs_bind_groups,
                accumulation,
            } => {
                times.force_calculation = submit("force", &|e| {
                    let springs = self.uniforms.spring_count;
                    dispatch(
                        e,
                        "spring forces",
                        springs_pipeline,
                        &springs_bind_groups[current],
                        springs,
                        None,
                    );
                })?;
                times.force_accumulation = Some(submit("accumulation", &|e| {
                    self.encode_accumulation(e, accumulation, &mut None);
                })?);
            }
        }
        times.integration = submit("integration", &|e| {
            dispatch(
                e,
                "integrate",
                &self.integrate,
                &self.integrate_groups[current],
                n,
                None,
            );
        })?;
        times.collision = submit("collision", &|e| {
            if let Some(pass) = &self.collide {
                pass.encode(e, current, n, None);
            }
            if let Some(pass) = &self.self_collide {
                pass.encode(e, current, None);
            }
            dispatch(e, "tick", &self.tick, &self.tick_group, 1, None);
        })?;
        Ok(times)
    }
}

fn add_phase(times: &mut PhaseTimes, phase: &Phase, duration: Duration) {
    match phase {
        Phase::External => times.external += duration,
        Phase::Force => times.force_calculation += duration,
        Phase::Accumulation => *times.force_accumulation.get_or_insert(Duration::ZERO) += duration,
        Phase::Integration => times.integration += duration,
        Phase::Collision => times.collision += duration,
    }
}

/// Hands out timestamp slot pairs to passes and remembers each pass's phase.
struct PassTimer<'a> {
    query_set: &'a wgpu::QuerySet,
    phases: Vec<Phase>,
}

impl<'a> PassTimer<'a> {
    fn next(
        timer: &mut Option<PassTimer<'a>>,
        phase: Phase,
    ) -> Option<wgpu::ComputePassTimestampWrites<'a>> {
        let timer = timer.as_mut()?;
        let index = 2 * timer.phases.len() as u32;
        if index + 2 > TIMESTAMP_SLOTS {
            return None;
        }
        timer.phases.push(phase);
        Some(wgpu::ComputePassTimestampWrites {
            query_set: timer.query_set,
            beginning_of_pass_write_index: Some(index),
            end_of_pass_write_index: Some(index + 1),
        })
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

impl RunError {
    fn into_gpu(self) -> GpuError {
        match self {
            Self::Sim(e) => GpuError::Validation(e.to_string()),
            Self::Gpu(e) => e,
        }
    }
}

/// The four `vec4` per collider that collide.wgsl reads.
fn collider_entries(colliders: &[Collider]) -> Vec<[f32; 4]> {
    colliders
        .iter()
        .flat_map(|c| {
            let v = c.velocity.as_vec3();
            // Entry 3: a dynamic ball's force and restitution, or a capsule mark, a script's
            // repeat flag and keyframe count.
            let capsule = if matches!(c.shape, Shape::Capsule { .. }) {
                1.0
            } else {
                0.0
            };
            let (inverse_mass, script) = match (c.dynamics, c.path) {
                (Some(d), _) => {
                    let f = d.force.as_vec3();
                    ((1.0 / d.mass) as f32, [f.x, f.y, f.z, d.restitution as f32])
                }
                (None, Some(path)) => {
                    let repeat = if path.repeat { 1.0 } else { 0.0 };
                    (0.0, [capsule, 0.0, repeat, path.keyframes().len() as f32])
                }
                (None, None) => (0.0, [capsule, 0.0, 0.0, 0.0]),
            };
            let motion = [v.x, v.y, v.z, inverse_mass];
            let friction = c.friction as f32;
            let (place, surface) = match c.shape {
                Shape::Sphere { center, radius } => {
                    let (p, w) = (center.as_vec3(), c.spin.as_vec3());
                    ([p.x, p.y, p.z, radius as f32], [w.x, w.y, w.z, friction])
                }
                Shape::Plane { point, normal } => {
                    let (p, n) = (point.as_vec3(), normal.as_vec3());
                    ([p.x, p.y, p.z, -1.0], [n.x, n.y, n.z, friction])
                }
                Shape::Capsule { start, end, radius } => {
                    let (p, a) = (start.as_vec3(), (end - start).as_vec3());
                    ([p.x, p.y, p.z, radius as f32], [a.x, a.y, a.z, friction])
                }
            };
            [place, surface, motion, script]
        })
        .collect()
}

/// `MAX_KEYFRAMES` slots `(t, x, y, z)` per collider for paths.wgsl.
fn keyframe_entries(colliders: &[Collider]) -> Vec<[f32; 4]> {
    colliders
        .iter()
        .flat_map(|c| {
            let mut slots = [[0.0f32; 4]; MAX_KEYFRAMES];
            if let Some(path) = c.path {
                for (slot, (t, p)) in slots.iter_mut().zip(path.keyframes()) {
                    let p = p.as_vec3();
                    *slot = [*t as f32, p.x, p.y, p.z];
                }
            }
            slots
        })
        .collect()
}

/// Positions as the `vec4` per vertex (w = 1) that GPU position buffers hold.
pub fn positions_to_vec4(positions: &[DVec3]) -> Vec<[f32; 4]> {
    positions
        .iter()
        .map(|p| {
            let p = p.as_vec3();
            [p.x, p.y, p.z, 1.0]
        })
        .collect()
}

/// Valence-sorted processing order (the paper's layout): slot -> vertex.
fn valence_sorted_order(model: &Model) -> Vec<u32> {
    let mut order: Vec<u32> = (0..model.vertex_count() as u32).collect();
    order.sort_by_key(|&v| std::cmp::Reverse(model.adjacency.valence(v as usize)));
    order
}

fn bytes_of<T>(data: &[T]) -> u64 {
    std::mem::size_of_val(data) as u64
}

/// Builds the force and accumulation passes; returns them with the bytes of their static data
/// and of their per-step buffers.
fn build_topology(
    ctx: &GpuContext,
    model: &Model,
    method: GpuMethod,
    uniforms: &wgpu::Buffer,
    positions: &[wgpu::Buffer; 2],
    forces: &wgpu::Buffer,
    status: &wgpu::Buffer,
) -> Result<(Topology, u64, u64), GpuError> {
    let adjacency = &model.adjacency;
    let n = model.vertex_count();
    match method {
        GpuMethod::Gather => {
            let order = valence_sorted_order(model);
            let mut offsets = Vec::with_capacity(n + 1);
            let mut entries = Vec::with_capacity(adjacency.neighbors.len());
            offsets.push(0u32);
            for &v in &order {
                for k in adjacency.range(v as usize) {
                    let spring = adjacency.springs[k] as usize;
                    entries.push(GatherEntry {
                        neighbor: adjacency.neighbors[k],
                        rest_length: model.rest_lengths[spring] as f32,
                        stiffness: model.stiffnesses[spring] as f32,
                    });
                }
                offsets.push(entries.len() as u32);
            }
            gpu::check_binding_size(ctx, "gather adjacency", bytes_of(&entries))?;
            let none = wgpu::BufferUsages::empty();
            let order_buffer = storage(ctx, "gather order", &order, none);
            let offsets_buffer = storage(ctx, "gather offsets", &offsets, none);
            let entries_buffer = storage(ctx, "gather entries", &entries, none);
            let pipeline = compute_pipeline(ctx, "gather forces", kernels::FORCE_GATHER, "main")?;
            let layout = pipeline.get_bind_group_layout(0);
            let bind_groups = [0, 1].map(|current| {
                bind_group(
                    ctx,
                    "gather forces",
                    &layout,
                    &[
                        (0, uniforms.as_entire_binding()),
                        (1, positions[current].as_entire_binding()),
                        (2, order_buffer.as_entire_binding()),
                        (3, offsets_buffer.as_entire_binding()),
                        (4, entries_buffer.as_entire_binding()),
                        (5, forces.as_entire_binding()),
                    ],
                )
            });
            let bytes = bytes_of(&order) + bytes_of(&offsets) + bytes_of(&entries);
            Ok((
                Topology::Gather {
                    pipeline,
                    bind_groups,
                },
                bytes,
                0,
            ))
        }
        GpuMethod::Scatter(accumulation) => {
            let springs: Vec<GpuSpring> = model
                .spring_ends
                .iter()
                .enumerate()
                .map(|(s, [a, b])| GpuSpring {
                    a: *a,
                    b: *b,
                    rest_length: model.rest_lengths[s] as f32,
                    stiffness: model.stiffnesses[s] as f32,
                })
                .collect();
            gpu::check_binding_size(ctx, "springs", bytes_of(&springs))?;
            let springs_buffer = storage(ctx, "springs", &springs, wgpu::BufferUsages::empty());
            let spring_forces = zeroed(
                ctx,
                "spring forces",
                vec4s(springs.len()),
                wgpu::BufferUsages::empty(),
            );
            let springs_pipeline =
                compute_pipeline(ctx, "spring forces", kernels::FORCE_SPRINGS, "main")?;
            let layout = springs_pipeline.get_bind_group_layout(0);
            let springs_bind_groups = [0, 1].map(|current| {
                bind_group(
                    ctx,
                    "spring forces",
                    &layout,
                    &[
                        (0, uniforms.as_entire_binding()),
                        (1, positions[current].as_entire_binding()),
                        (2, springs_buffer.as_entire_binding()),
                        (3, spring_forces.as_entire_binding()),
                    ],
                )
            });
            let shared = Shared {
                ctx,
                uniforms,
                springs: &springs_buffer,
                spring_forces: &spring_forces,
                forces,
                status,
            };
            let (accumulation, accumulation_static, accumulation_per_step) =
                build_accumulation(&shared, model, accumulation)?;
            Ok((
                Topology::Scatter {
                    springs_pipeline,
                    springs_bind_groups,
                    accumulation,
                },
                bytes_of(&springs) + accumulation_static,
                vec4s(springs.len()) + accumulation_per_step,
            ))
        }
    }
}

/// Buffers every accumulation binds.
struct Shared<'a> {
    ctx: &'a GpuContext,
    uniforms: &'a wgpu::Buffer,
    springs: &'a wgpu::Buffer,
    spring_forces: &'a wgpu::Buffer,
    forces: &'a wgpu::Buffer,
    status: &'a wgpu::Buffer,
}

fn build_accumulation(
    shared: &Shared<'_>,
    model: &Model,
    accumulation: Accumulation,
) -> Result<(AccumulationPass, u64, u64), GpuError> {
    let ctx = shared.ctx;
    let n = model.vertex_count();
    match accumulation {
        Accumulation::AtomicF32 => {
            let pipeline = compute_pipeline(
                ctx,
                "accumulate atomic-f32",
                kernels::ACCUMULATE_ATOMIC_F32,
                "main",
            )?;
            let bind_group = bind_group(
                ctx,
                "accumulate atomic-f32",
                &pipeline.get_bind_group_layout(0),
                &[
                    (0, shared.uniforms.as_entire_binding()),
                    (1, shared.springs.as_entire_binding()),
                    (2, shared.spring_forces.as_entire_binding()),
                    (3, shared.forces.as_entire_binding()),
                ],
            );
            Ok((
                AccumulationPass::AtomicF32 {
                    pipeline,
                    bind_group,
                },
                0,
                0,
            ))
        }
        Accumulation::AtomicFixed => {
            let accumulators = zeroed(
                ctx,
                "fixed-point accumulators",
                vec4s(n),
                wgpu::BufferUsages::COPY_DST,
            );
            let accumulate = compute_pipeline(
                ctx,
                "accumulate atomic-fixed",
                kernels::ACCUMULATE_FIXED,
                "main",
            )?;
            let accumulate_group = bind_group(
                ctx,
                "accumulate atomic-fixed",
                &accumulate.get_bind_group_layout(0),
                &[
                    (0, shared.uniforms.as_entire_binding()),
                    (1, shared.springs.as_entire_binding()),
                    (2, shared.spring_forces.as_entire_binding()),
                    (3, accumulators.as_entire_binding()),
                    (4, shared.status.as_entire_binding()),
                ],
            );
            let resolve =
                compute_pipeline(ctx, "resolve atomic-fixed", kernels::RESOLVE_FIXED, "main")?;
            let resolve_group = bind_group(
                ctx,
                "resolve atomic-fixed",
                &resolve.get_bind_group_layout(0),
                &[
                    (0, shared.uniforms.as_entire_binding()),
                    (1, accumulators.as_entire_binding()),
                    (2, shared.forces.as_entire_binding()),
                ],
            );
            let pass = AccumulationPass::Fixed {
                accumulate,
                accumulate_group,
                resolve,
                resolve_group,
                accumulators,
            };
            Ok((pass, 0, vec4s(n)))
        }
        Accumulation::Incidence => {
            let adjacency = &model.adjacency;
            let offsets: Vec<u32> = adjacency.offsets.clone();
            let entries: Vec<u32> = (0..n)
                .flat_map(|v| {
                    adjacency.range(v).map(move |k| {
                        let spring = adjacency.springs[k];
                        let far = model.spring_ends[spring as usize][1] as usize == v;
                        spring | if far { 0x8000_0000 } else { 0 }
                    })
                })
                .collect();
            let none = wgpu::BufferUsages::empty();
            let offsets_buffer = storage(ctx, "incidence offsets", &offsets, none);
            let entries_buffer = storage(ctx, "incidence entries", &entries, none);
            let pipeline = compute_pipeline(
                ctx,
                "accumulate incidence",
                kernels::ACCUMULATE_INCIDENCE,
                "main",
            )?;
            let bind_group = bind_group(
                ctx,
                "accumulate incidence",
                &pipeline.get_bind_group_layout(0),
                &[
                    (0, shared.uniforms.as_entire_binding()),
                    (1, shared.spring_forces.as_entire_binding()),
                    (2, offsets_buffer.as_entire_binding()),
                    (3, entries_buffer.as_entire_binding()),
                    (4, shared.forces.as_entire_binding()),
                ],
            );
            let bytes = bytes_of(&offsets) + bytes_of(&entries);
            Ok((
                AccumulationPass::Incidence {
                    pipeline,
                    bind_group,
                },
                bytes,
                0,
            ))
        }
        Accumulation::BlendR32f | Accumulation::BlendR16f | Accumulation::BlendRgba8 => {
            build_blend(shared, model, accumulation)
        }
    }
}

fn build_blend(
    shared: &Shared<'_>,
    model: &Model,
    accumulation: Accumulation,
) -> Result<(AccumulationPass, u64, u64), GpuError> {
    let ctx = shared.ctx;
    let n = model.vertex_count() as u32;
    let format = accumulation.blend_format().ok_or_else(|| {
        GpuError::Validation(format!(
            "{} is not a blend accumulation",
            accumulation.name()
        ))
    })?;
    let width = BLEND_WIDTH.min(n.max(1));
    let height = n.div_ceil(width).max(1);
    let max_dimension = ctx.device.limits().max_texture_dimension_2d;
    if height > max_dimension {
        return Err(GpuError::TooLarge {
            what: "blend force target rows",
            needed: u64::from(height),
            limit: u64::from(max_dimension),
            adapter: ctx.info.name.clone(),
        });
    }
    let split = accumulation == Accumulation::BlendRgba8;
    // Two targets: positive and negative parts. Float targets write only the first; the second
    // stays zero (textures are created cleared) so one resolve kernel serves every format.
    let textures: Vec<wgpu::Texture> = ["force target (positive)", "force target (negative)"]
        .iter()
        .map(|label| {
            ctx.device.create_texture(&wgpu::TextureDescriptor {
                label: Some(label),
                size: wgpu::Extent3d {
                    width,
                    height,
                    depth_or_array_layers: 1,
                },
                mip_level_count: 1,
                sample_count: 1,
                dimension: wgpu::TextureDimension::D2,
                format,
                usage: wgpu::TextureUsages::RENDER_ATTACHMENT
                    | wgpu::TextureUsages::TEXTURE_BINDING,
                view_formats: &[],
            })
        })
        .collect();
    let views: Vec<wgpu::TextureView> = textures
        .iter()
        .map(|t| t.create_view(&Default::default()))
        .collect();
    let scope = ctx.device.push_error_scope(wgpu::ErrorFilter::Validation);
    let module = ctx
        .device
        .create_shader_module(wgpu::ShaderModuleDescriptor {
            label: Some("accumulate blend"),
            source: wgpu::ShaderSource::Wgsl(kernels::ACCUMULATE_BLEND.into()),
        });
    let additive = wgpu::BlendComponent {
        src_factor: wgpu::BlendFactor::One,
        dst_factor: wgpu::BlendFactor::One,
        operation: wgpu::BlendOperation::Add,
    };
    let target = Some(wgpu::ColorTargetState {
        format,
        blend: Some(wgpu::BlendState {
            color: additive,
            alpha: additive,
        }),
        write_mask: wgpu::ColorWrites::ALL,
    });
    let targets = if split {
        vec![target.clone(), target]
    } else {
        vec![target]
    };
    let pipeline = ctx
        .device
        .create_render_pipeline(&wgpu::RenderPipelineDescriptor {
            label: Some("accumulate blend"),
            layout: None,
            vertex: wgpu::VertexState {
                module: &module,
                entry_point: Some("vs_main"),
                compilation_options: Default::default(),
                buffers: &[],
            },
            primitive: wgpu::PrimitiveState {
                topology: wgpu::PrimitiveTopology::PointList,
                ..Default::default()
            },
            depth_stencil: None,
            multisample: Default::default(),
            fragment: Some(wgpu::FragmentState {
                module: &module,
                entry_point: Some(if split { "fs_split" } else { "fs_signed" }),
                compilation_options: Default::default(),
                targets: &targets,
            }),
            multiview_mask: None,
            cache: None,
        });
    if let Some(error) = pollster::block_on(scope.pop()) {
        return Err(GpuError::Validation(format!("accumulate blend: {error}")));
    }
    let blend_group = bind_group(
        ctx,
        "accumulate blend",
        &pipeline.get_bind_group_layout(0),
        &[
            (0, shared.uniforms.as_entire_binding()),
            (1, shared.springs.as_entire_binding()),
            (2, shared.spring_forces.as_entire_binding()),
        ],
    );
    let resolve = compute_pipeline(ctx, "resolve blend", kernels::RESOLVE_BLEND, "main")?;
    let resolve_group = bind_group(
        ctx,
        "resolve blend",
        &resolve.get_bind_group_layout(0),
        &[
            (0, shared.uniforms.as_entire_binding()),
            (1, wgpu::BindingResource::TextureView(&views[0])),
            (2, wgpu::BindingResource::TextureView(&views[1])),
            (3, shared.forces.as_entire_binding()),
        ],
    );
    let texel_bytes = u64::from(format.block_copy_size(None).unwrap_or(16));
    let target_bytes = 2 * u64::from(width) * u64::from(height) * texel_bytes;
    let used_targets = if split {
        views
    } else {
        views.into_iter().take(1).collect()
    };
    let pass = AccumulationPass::Blend {
        pipeline,
        bind_group: blend_group,
        targets: used_targets,
        resolve,
        resolve_group,
    };
    Ok((pass, 0, target_bytes))
}

/// Point forces and drags per vertex: `[(force, drag stiffness), (drag target, 0)]`. Several
/// drags on one vertex combine into one of summed stiffness toward their weighted target.
fn point_and_drag(model: &Model, params: &SimParams) -> Vec<[f32; 4]> {
    let n = model.vertex_count();
    let mut force = vec![DVec3::ZERO; n];
    let mut stiffness = vec![0.0f64; n];
    let mut weighted_target = vec![DVec3::ZERO; n];
    for point in &params.point_forces {
        force[point.vertex as usize] += point.force;
    }
    for drag in &params.drags {
        for &v in &drag.vertices {
            stiffness[v as usize] += drag.stiffness;
            weighted_target[v as usize] += drag.stiffness * drag.target;
        }
    }
    (0..n)
        .flat_map(|v| {
            let target = if stiffness[v] > 0.0 {
                weighted_target[v] / stiffness[v]
            } else {
                DVec3::ZERO
            };
            let f = force[v].as_vec3();
            let t = target.as_vec3();
            [[f.x, f.y, f.z, stiffness[v] as f32], [t.x, t.y, t.z, 0.0]]
        })
        .collect()
}

impl GpuSolver {
    fn build_external(&mut self, params: &SimParams) -> Result<Option<ExternalPass>, GpuError> {
        if params.point_forces.is_empty() && params.drags.is_empty() && params.wind.is_none() {
            return Ok(None);
        }
        let ctx = &*self.context;
        let model = &self.model;
        let n = model.vertex_count();
        let none = wgpu::BufferUsages::empty();
        let point_and_drag = storage(
            ctx,
            "point forces and drags",
            &point_and_drag(model, params),
            none,
        );
        let wind_value = params.wind.map_or([0.0; 4], |w| {
            let v = w.velocity.as_vec3();
            [v.x, v.y, v.z, w.coefficient as f32]
        });
        let wind_buffer = ctx.device.create_buffer(&wgpu::BufferDescriptor {
            label: Some("wind"),
            size: 16,
            usage: wgpu::BufferUsages::UNIFORM | wgpu::BufferUsages::COPY_DST,
            mapped_at_creation: false,
        });
        ctx.queue
            .write_buffer(&wind_buffer, 0, bytemuck::cast_slice(&wind_value));
        let windy = params.wind.is_some();
        let triangles: Vec<[u32; 4]> = if windy {
            model
                .triangles
                .iter()
                .map(|t| [t[0], t[1], t[2], 0])
                .collect()
        } else {
            Vec::new()
        };
        let mut lists = vec![0u32; n + 1];
        for t in &triangles {
            for &v in &t[..3] {
                lists[v as usize + 1] += 1;
            }
        }
        for v in 0..n {
            lists[v + 1] += lists[v];
        }
        let mut cursor = lists.clone();
        lists.resize(n + 1 + 3 * triangles.len(), 0);
        for (index, t) in triangles.iter().enumerate() {
            for &v in &t[..3] {
                lists[n + 1 + cursor[v as usize] as usize] = index as u32;
                cursor[v as usize] += 1;
            }
        }
        let triangle_buffer = storage(ctx, "wind triangles", &triangles, none);
        let triangle_forces = zeroed(ctx, "wind triangle forces", vec4s(triangles.len()), none);
        let vertex_triangles = storage(ctx, "vertex triangles", &lists, none);
        let vertices = compute_pipeline(ctx, "external forces", kernels::EXTERNAL, "vertices")?;
        let layout = vertices.get_bind_group_layout(0);
        let vertex_groups = [0, 1].map(|current| {
            bind_group(
                ctx,
                "external forces",
                &layout,
                &[
                    (0, self.uniform_buffer.as_entire_binding()),
                    (1, self.positions[current].as_entire_binding()),
                    (3, point_and_drag.as_entire_binding()),
                    (6, triangle_forces.as_entire_binding()),
                    (7, vertex_triangles.as_entire_binding()),
                    (8, self.extra_forces.as_entire_binding()),
                ],
            )
        });
        let wind = if windy {
            let pipeline = compute_pipeline(
                ctx,
                "wind per triangle",
                kernels::EXTERNAL,
                "wind_triangles",
            )?;
            let layout = pipeline.get_bind_group_layout(0);
            let groups = [0, 1].map(|current| {
                bind_group(
                    ctx,
                    "wind per triangle",
                    &layout,
                    &[
                        (0, self.uniform_buffer.as_entire_binding()),
                        (1, self.positions[current].as_entire_binding()),
                        (2, self.deltas.as_entire_binding()),
                        (4, wind_buffer.as_entire_binding()),
                        (5, triangle_buffer.as_entire_binding()),
                        (6, triangle_forces.as_entire_binding()),
                    ],
                )
            });
            Some((pipeline, groups))
        } else {
            None
        };
        self.uniforms.triangle_count = triangles.len() as u32;
        let bytes = 2 * vec4s(n) + 2 * vec4s(triangles.len()) + bytes_of(&lists) + vec4s(n);
        Ok(Some(ExternalPass {
            wind,
            vertices,
            vertex_groups,
            bytes,
        }))
    }

    /// The collider pass: (re)built when the colliders change kind or number; otherwise the
    /// new settings are written in place so dynamic balls keep where they are and how they move.
    fn build_collide(&mut self, params: &SimParams) -> Result<(), GpuError> {
        let ctx = &*self.context;
        let entries = collider_entries(&params.colliders);
        if let Some(pass) = &self.collide
            && hooke_core::collide::same_kinds(&self.collider_settings, &params.colliders)
        {
            // Same kinds: rewrite settings, but not the place and motion of dynamic balls.
            for (k, (collider, entry)) in params.colliders.iter().zip(entries.chunks(4)).enumerate()
            {
                let base = (k * 4 * 16) as u64;
                if collider.dynamics.is_some() {
                    // Only the friction of entry 1: its xyz is the ball's spin.
                    ctx.queue.write_buffer(
                        &pass.colliders,
                        base + 28,
                        bytemuck::bytes_of(&entry[1][3]),
                    );
                    ctx.queue.write_buffer(
                        &pass.colliders,
                        base + 48,
                        bytemuck::cast_slice(&entry[3..4]),
                    );
                } else {
                    ctx.queue
                        .write_buffer(&pass.colliders, base, bytemuck::cast_slice(entry));
                }
            }
            ctx.queue.write_buffer(
                &pass.keyframes,
                0,
                bytemuck::cast_slice(&keyframe_entries(&params.colliders)),
            );
            self.collider_settings = params.colliders.clone();
            return Ok(());
        }
        self.collider_settings = params.colliders.clone();
        if params.colliders.is_empty() {
            self.collide = None;
            return Ok(());
        }
        let colliders = storage(
            ctx,
            "colliders",
            &entries,
            wgpu::BufferUsages::COPY_SRC | wgpu::BufferUsages::COPY_DST,
        );
        let keyframes = storage(
            ctx,
            "collider keyframes",
            &keyframe_entries(&params.colliders),
            wgpu::BufferUsages::COPY_DST,
        );
        let dynamic = hooke_core::collide::any_dynamic(&params.colliders);
        let reactions = if dynamic {
            let bytes = vec4s(self.model.vertex_count() * params.colliders.len());
            gpu::check_binding_size(&self.context, "collider reactions", bytes)?;
            zeroed(
                ctx,
                "collider reactions",
                bytes,
                wgpu::BufferUsages::empty(),
            )
        } else {
            zeroed(
                ctx,
                "collider reactions (none)",
                16,
                wgpu::BufferUsages::empty(),
            )
        };
        let pipeline = compute_pipeline(ctx, "collide", kernels::COLLIDE, "main")?;
        let layout = pipeline.get_bind_group_layout(0);
        let groups = [0, 1].map(|current| {
            bind_group(
                ctx,
                "collide",
                &layout,
                &[
                    (0, self.uniform_buffer.as_entire_binding()),
                    (1, self.positions[current].as_entire_binding()),
                    (2, self.positions[1 - current].as_entire_binding()),
                    (3, self.deltas.as_entire_binding()),
                    (4, self.scales.as_entire_binding()),
                    (5, colliders.as_entire_binding()),
                    (6, self.status.as_entire_binding()),
                    (7, reactions.as_entire_binding()),
                    (12, keyframes.as_entire_binding()),
                ],
            )
        });
        let balls = if dynamic {
            let advance = compute_pipeline(ctx, "balls advance", kernels::BALLS, "advance")?;
            let contacts = compute_pipeline(ctx, "balls contacts", kernels::BALLS, "contacts")?;
            let advance_group = bind_group(
                ctx,
                "balls advance",
                &advance.get_bind_group_layout(0),
                &[
                    (0, self.uniform_buffer.as_entire_binding()),
                    (1, colliders.as_entire_binding()),
                    (2, reactions.as_entire_binding()),
                    (4, self.status.as_entire_binding()),
                ],
            );
            let contacts_group = bind_group(
                ctx,
                "balls contacts",
                &contacts.get_bind_group_layout(0),
                &[
                    (0, self.uniform_buffer.as_entire_binding()),
                    (1, colliders.as_entire_binding()),
                    (3, self.status.as_entire_binding()),
                    (12, keyframes.as_entire_binding()),
                ],
            );
            Some(BallsPass {
                advance,
                advance_group,
                contacts,
                contacts_group,
            })
        } else {
            None
        };
        self.collide = Some(CollidePass {
            pipeline,
            groups,
            colliders,
            count: params.colliders.len() as u32,
            keyframes,
            balls,
        });
        Ok(())
    }

    /// Records, into `encoder`, copies of the sphere colliders' current places (centre, radius)
    /// into `target`, one `vec4` per sphere in collider order: how a renderer draws dynamic
    /// balls without reading them back.
    pub fn copy_spheres(&self, encoder: &mut wgpu::CommandEncoder, target: &wgpu::Buffer) {
        let Some(pass) = &self.collide else { return };
        let spheres = self
            .collider_settings
            .iter()
            .enumerate()
            .filter(|(_, c)| matches!(c.shape, Shape::Sphere { .. }));
        for (slot, (k, collider)) in spheres.enumerate() {
            if collider.dynamics.is_some() {
                encoder.copy_buffer_to_buffer(
                    &pass.colliders,
                    (k * 64) as u64,
                    target,
                    (slot * 16) as u64,
                    16,
                );
            }
        }
    }

    fn apply_params(&mut self, params: &SimParams) -> Result<(), GpuError> {
        let dt = params.dt;
        let scales: Vec<[f32; 4]> = self
            .model
            .masses
            .iter()
            .zip(&self.model.pinned)
            .map(|(m, pinned)| {
                if *pinned {
                    [0.0; 4]
                } else {
                    [
                        (dt * dt / m) as f32,
                        (1.0 - params.damping * dt / m) as f32,
                        0.0,
                        0.0,
                    ]
                }
            })
            .collect();
        self.context
            .queue
            .write_buffer(&self.scales, 0, bytemuck::cast_slice(&scales));
        let g = (params.gravity * dt * dt).as_vec3();
        self.uniforms.gravity_step = [g.x, g.y, g.z, 0.0];
        self.uniforms.inverse_dt = (1.0 / dt) as f32;
        self.dt = dt;
        self.uniforms.triangle_count = 0;
        self.external = self.build_external(params)?;
        self.uniforms.has_extra = u32::from(self.external.is_some());
        self.build_collide(params)?;
        self.uniforms.collider_count = params.colliders.len() as u32;
        self.uniforms.dynamic_count = params
            .colliders
            .iter()
            .filter(|c| c.dynamics.is_some())
            .count() as u32;
        self.uniforms.collision_thickness = params.collision_thickness as f32;
        self.self_collide = match &params.self_collision {
            Some(config) => Some(SelfCollidePass::new(
                &self.context,
                &self.model,
                config,
                SolverBuffers {
                    positions: &self.positions,
                    deltas: &self.deltas,
                    scales: &self.scales,
                },
            )?),
            None => None,
        };
        self.write_uniforms();
        self.context.take_error()
    }

    /// Up to this many steps go into one command buffer.
    const STEPS_PER_SUBMISSION: u32 = 256;
}

impl Solver for GpuSolver {
    fn describe(&self) -> String {
        format!(
            "gpu {} (f32, {})",
            self.method.name(),
            self.context.info.name
        )
    }

    fn set_params(&mut self, params: &SimParams) {
        if let Err(error) = self.apply_params(params) {
            // The trait cannot fail here; the error resurfaces from the next step.
            self.context.report(error.to_string());
        }
    }

    fn step(&mut self, steps: u32) -> Result<(), SimError> {
        let mut remaining = steps;
        while remaining > 0 {
            let batch = remaining.min(Self::STEPS_PER_SUBMISSION);
            self.run_steps(batch).map_err(|e| match e {
                RunError::Sim(e) => e,
                RunError::Gpu(e) => SimError::Device(e.to_string()),
            })?;
            remaining -= batch;
        }
        Ok(())
    }

    fn read_state(&self) -> State {
        let n = self.model.vertex_count();
        let bytes = read_back(
            &self.context,
            &[
                (self.current_positions(), vec4s(n)),
                (&self.deltas, vec4s(n)),
            ],
        );
        let Ok(bytes) = bytes else {
            // A lost device leaves nothing to read; NaN makes the loss visible to health checks.
            let nan = vec![DVec3::NAN; n];
            return State {
                positions: nan.clone(),
                previous_positions: nan,
            };
        };
        let positions: Vec<[f32; 4]> = bytemuck::pod_collect_to_vec(&bytes[0]);
        let deltas: Vec<[f32; 4]> = bytemuck::pod_collect_to_vec(&bytes[1]);
        let as_dvec = |v: &[f32; 4]| DVec3::new(f64::from(v[0]), f64::from(v[1]), f64::from(v[2]));
        let positions: Vec<DVec3> = positions.iter().map(as_dvec).collect();
        let previous_positions = positions
            .iter()
            .zip(&deltas)
            .map(|(x, d)| *x - as_dvec(d))
            .collect();
        State {
            positions,
            previous_positions,
        }
    }

    fn write_state(&mut self, state: &State) {
        let positions = positions_to_vec4(&state.positions);
        let deltas: Vec<[f32; 4]> = state
            .positions
            .iter()
            .zip(&state.previous_positions)
            .map(|(p, q)| {
                let d = (*p - *q).as_vec3();
                [d.x, d.y, d.z, 0.0]
            })
            .collect();
        let queue = &self.context.queue;
        queue.write_buffer(
            self.current_positions(),
            0,
            bytemuck::cast_slice(&positions),
        );
        queue.write_buffer(&self.deltas, 0, bytemuck::cast_slice(&deltas));
    }

    fn steps_taken(&self) -> u64 {
        self.steps_taken
    }

    fn colliders(&self) -> Vec<Collider> {
        let t = self.steps_taken as f64 * self.dt;
        let mut placed = hooke_core::collide::placed(&self.collider_settings, t);
        let Some(pass) = &self.collide else {
            return placed;
        };
        if !hooke_core::collide::any_dynamic(&placed) {
            return placed;
        }
        // Dynamic balls live on the GPU: read their place and motion back.
        let entries: Vec<[f32; 4]> =
            match read_back(&self.context, &[(&pass.colliders, pass.colliders.size())]) {
                Ok(bytes) => bytemuck::pod_collect_to_vec(&bytes[0]),
                Err(error) => {
                    eprintln!("colliders: {error}; showing the balls where they started");
                    return placed;
                }
            };
        for (collider, entry) in placed.iter_mut().zip(entries.chunks(4)) {
            if collider.dynamics.is_none() {
                continue;
            }
            if let Shape::Sphere { center, .. } = &mut collider.shape {
                *center = glam::Vec3::from_slice(&entry[0][..3]).as_dvec3();
            }
            collider.velocity = glam::Vec3::from_slice(&entry[2][..3]).as_dvec3();
            collider.spin = glam::Vec3::from_slice(&entry[1][..3]).as_dvec3();
        }
        placed
    }
}
