//! What the viewer simulates and how the panel changes it: the solver choice, live parameters,
//! the grabbed vertex, and status checks that never make a frame wait.

use std::sync::Arc;

use glam::{DVec3, Vec3};
use hooke_core::collide::{self, Collider};
use hooke_core::scene::Scene;
use hooke_core::selfcollide::SelfCollision;
use hooke_core::stability::stability_limit;
use hooke_core::{Drag, Model, PhaseTimes, SimParams, Solver, State, Wind};
use hooke_cpu::{CpuOptions, CpuSolver, Method};
use hooke_gpu::render::AsyncReadback;
use hooke_gpu::wgpu;
use hooke_gpu::{Accumulation, GpuContext, GpuMethod, GpuSolver, TimingSource, positions_to_vec4};

/// Which solver runs.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Choice {
    Gpu(GpuMethod),
    Cpu(Method),
}

impl Choice {
    /// The solver the command line asks for.
    pub fn from_args(args: &crate::solvers::SolverArgs) -> anyhow::Result<Self> {
        use crate::solvers::{Backend, MethodArg};
        Ok(match (args.backend.unwrap_or(Backend::Gpu), args.method) {
            (Backend::Reference, _) => {
                anyhow::bail!("the viewer runs the cpu or gpu backend, not the reference")
            }
            (Backend::Cpu, method) => Choice::Cpu(method.unwrap_or(MethodArg::Gather).into()),
            (Backend::Gpu, Some(MethodArg::Gather)) => Choice::Gpu(GpuMethod::Gather),
            (Backend::Gpu, _) => Choice::Gpu(GpuMethod::Scatter(args.accumulation.into())),
        })
    }

    pub fn label(self) -> String {
        match self {
            Self::Gpu(m) => format!("gpu {}", m.name()),
            Self::Cpu(m) => format!("cpu {} (uploads positions each frame)", m.name()),
        }
    }
}

enum Active {
    Gpu(Box<GpuSolver>),
    /// The CPU solver's positions are copied into this vec4 buffer every frame for drawing.
    Cpu(Box<CpuSolver>, wgpu::Buffer),
}

/// Steps between non-blocking status checks of the GPU solver.
const STATUS_EVERY: u64 = 30;

pub struct Simulation {
    context: Arc<GpuContext>,
    scene: Scene,
    model: Model,
    active: Active,
    pub choice: Choice,
    pub choices: Vec<Choice>,
    pub stiffness_scale: f64,
    /// Set by the panel; the model is rebuilt before the next frame's steps.
    pub stiffness_changed: bool,
    pub damping: f64,
    /// dt as a fraction of the stability bound.
    pub dt_fraction: f64,
    pub max_stable_dt: f64,
    pub steps_per_frame: u32,
    pub gravity_y: f64,
    pub wind_enabled: bool,
    pub wind_heading_degrees: f64,
    pub wind_speed: f64,
    pub wind_coefficient: f64,
    pub self_collision_enabled: bool,
    /// The ball the panel and keys push (collider index), how hard, and where to now.
    pub selected_ball: Option<usize>,
    pub push_newtons: f64,
    push_direction: DVec3,
    /// The scene's self-collision setting, or one made for the mesh.
    pub self_collision: SelfCollision,
    pub paused: bool,
    pub step_once: bool,
    pub grab: Option<(u32, Vec3)>,
    pub message: Option<String>,
    pub phases: Option<(PhaseTimes, TimingSource)>,
    status: AsyncReadback,
    frames_since_status: u64,
}

impl Simulation {
    pub fn new(context: Arc<GpuContext>, scene: Scene, choice: Choice) -> anyhow::Result<Self> {
        let gpu_methods = GpuMethod::all().into_iter().filter(|m| match m {
            GpuMethod::Scatter(Accumulation::AtomicF32) => {
                context.has(wgpu::Features::SHADER_FLOAT32_ATOMIC)
            }
            GpuMethod::Scatter(Accumulation::BlendR32f) => {
                context.has(wgpu::Features::FLOAT32_BLENDABLE)
            }
            _ => true,
        });
        let choices: Vec<Choice> = gpu_methods
            .map(Choice::Gpu)
            .chain(Method::ALL.map(Choice::Cpu))
            .collect();
        let wind = scene.params.wind;
        let (heading, speed) = wind.map_or((0.0, 3.0), |w| {
            (
                w.velocity.z.atan2(w.velocity.x).to_degrees(),
                w.velocity.length(),
            )
        });
        let active = build(&context, choice, &scene.model, &scene.params)?;
        let status = AsyncReadback::new(&context, "status read-back", 16);
        Ok(Self {
            max_stable_dt: scene.max_stable_dt,
            dt_fraction: (scene.params.dt / scene.max_stable_dt).min(1.0),
            damping: scene.params.damping,
            gravity_y: scene.params.gravity.y,
            wind_enabled: wind.is_some(),
            wind_heading_degrees: heading,
            wind_speed: speed,
            wind_coefficient: wind.map_or(0.5, |w| w.coefficient),
            self_collision_enabled: scene.params.self_collision.is_some(),
            selected_ball: scene
                .params
                .colliders
                .iter()
                .position(|c| c.dynamics.is_some()),
            // Three times the heaviest ball's weight: enough to roll it into the cloth.
            push_newtons: 3.0
                * 9.81
                * scene
                    .params
                    .colliders
                    .iter()
                    .filter_map(|c| c.dynamics.map(|d| d.mass))
                    .fold(0.0, f64::max),
            push_direction: DVec3::ZERO,
            self_collision: scene
                .params
                .self_collision
                .unwrap_or_else(|| SelfCollision::for_model(&scene.model)),
            stiffness_scale: 1.0,
            stiffness_changed: false,
            steps_per_frame: 10,
            model: scene.model.clone(),
            scene,
            active,
            choice,
            choices,
            context,
            paused: false,
            step_once: false,
            grab: None,
            message: None,
            phases: None,
            status,
            frames_since_status: 0,
        })
    }

    pub fn model(&self) -> &Model {
        &self.model
    }

    pub fn dt(&self) -> f64 {
        self.dt_fraction * self.max_stable_dt
    }

    pub fn steps_taken(&self) -> u64 {
        self.solver().steps_taken()
    }

    /// The colliders to draw this frame: the CPU solver's own (no cost), or on the GPU the
    /// scripted places (dynamic balls are then copied in by [`Simulation::copy_spheres`]).
    pub fn colliders_to_draw(&self) -> Vec<Collider> {
        match &self.active {
            Active::Gpu(_) => {
                let t = self.steps_taken() as f64 * self.dt();
                collide::placed(&self.params().colliders, t)
            }
            Active::Cpu(s, _) => s.colliders(),
        }
    }

    /// Records copies of the GPU solver's ball places into the renderer's sphere buffer.
    pub fn copy_spheres(&self, encoder: &mut wgpu::CommandEncoder, target: &wgpu::Buffer) {
        if let Active::Gpu(solver) = &self.active {
            solver.copy_spheres(encoder, target);
        }
    }

    fn solver(&self) -> &dyn Solver {
        match &self.active {
            Active::Gpu(s) => s.as_ref(),
            Active::Cpu(s, _) => s.as_ref(),
        }
    }

    fn solver_mut(&mut self) -> &mut dyn Solver {
        match &mut self.active {
            Active::Gpu(s) => s.as_mut(),
            Active::Cpu(s, _) => s.as_mut(),
        }
    }

    /// The buffer the renderer draws: the GPU solver's own positions, or the CPU upload.
    pub fn positions(&self) -> &wgpu::Buffer {
        match &self.active {
            Active::Gpu(s) => s.current_positions(),
            Active::Cpu(_, buffer) => buffer,
        }
    }

    /// The parameters the controls describe.
    pub fn params(&self) -> SimParams {
        let heading = self.wind_heading_degrees.to_radians();
        let mass = |v: u32| self.model.masses[v as usize];
        SimParams {
            dt: self.dt(),
            damping: self.damping,
            gravity: DVec3::new(0.0, self.gravity_y, 0.0),
            wind: self.wind_enabled.then(|| Wind {
                velocity: DVec3::new(heading.cos(), 0.0, heading.sin()) * self.wind_speed,
                coefficient: self.wind_coefficient,
            }),
            point_forces: self.scene.params.point_forces.clone(),
            drags: self
                .grab
                .map(|(vertex, target)| Drag {
                    vertices: vec![vertex],
                    target: target.as_dvec3(),
                    // Stiff enough to lead the cloth, soft enough to stay stable: it adds a fifth
                    // of the stability budget to the grabbed vertex.
                    stiffness: 0.2 * mass(vertex) / (self.dt() * self.dt()),
                })
                .into_iter()
                .chain(self.scene.params.drags.iter().cloned())
                .collect(),
            colliders: self.pushed_colliders(),
            collision_thickness: self.scene.params.collision_thickness,
            self_collision: self.self_collision_enabled.then_some(self.self_collision),
        }
    }

    /// The scene's colliders, the selected ball with the user's push added to its force.
    fn pushed_colliders(&self) -> Vec<Collider> {
        let mut colliders = self.scene.params.colliders.clone();
        if let Some(k) = self.selected_ball
            && let Some(dynamics) = colliders.get_mut(k).and_then(|c| c.dynamics.as_mut())
        {
            dynamics.force += self.push_direction * self.push_newtons;
        }
        colliders
    }

    /// Sends the controls' parameters to the solver.
    pub fn apply_params(&mut self) {
        let params = self.params();
        self.solver_mut().set_params(&params);
    }

    /// Rebuilds the model (after a stiffness change) and the solver, keeping the state.
    pub fn rebuild(&mut self) {
        let state = self.solver().read_state();
        self.model = self.scene.model.clone();
        for k in &mut self.model.stiffnesses {
            *k *= self.stiffness_scale;
        }
        self.max_stable_dt = stability_limit(&self.model, self.damping).max_dt;
        self.replace_solver(self.choice, Some(state));
    }

    pub fn switch(&mut self, choice: Choice) {
        let state = self.solver().read_state();
        self.replace_solver(choice, Some(state));
    }

    /// A new solver; with `state`, it continues the running simulation (cloth and balls),
    /// without, it starts the scene again.
    fn replace_solver(&mut self, choice: Choice, state: Option<State>) {
        let mut params = self.params();
        if state.is_some() {
            // Dynamic balls carry on from where they are.
            for (setting, now) in params.colliders.iter_mut().zip(self.solver().colliders()) {
                if setting.dynamics.is_some() {
                    (setting.shape, setting.velocity) = (now.shape, now.velocity);
                }
            }
        }
        match build(&self.context, choice, &self.model, &params) {
            Ok(mut active) => {
                if let Some(state) = state {
                    match &mut active {
                        Active::Gpu(s) => s.write_state(&state),
                        Active::Cpu(s, _) => s.write_state(&state),
                    }
                }
                self.active = active;
                self.choice = choice;
                self.message = None;
            }
            Err(error) => self.message = Some(format!("{}: {error:#}", choice.label())),
        }
    }

    pub fn reset(&mut self) {
        self.replace_solver(self.choice, None);
        self.paused = false;
    }

    /// Dynamic balls the panel and keys can push, as collider indices.
    pub fn balls(&self) -> Vec<usize> {
        let colliders = &self.scene.params.colliders;
        (0..colliders.len())
            .filter(|&k| colliders[k].dynamics.is_some())
            .collect()
    }

    /// Pushes the selected ball along `direction` (unit or zero) with `push_newtons`.
    pub fn push(&mut self, direction: DVec3) {
        if direction != self.push_direction {
            self.push_direction = direction;
            self.apply_params();
        }
    }

    /// Records this frame's steps. GPU steps go into `encoder`; CPU steps run now and their
    /// positions are uploaded for drawing.
    pub fn encode_frame(&mut self, encoder: &mut wgpu::CommandEncoder) {
        if std::mem::take(&mut self.stiffness_changed) {
            self.rebuild();
        }
        let steps = if self.paused && !self.step_once {
            0
        } else if self.step_once {
            1
        } else {
            self.steps_per_frame
        };
        self.step_once = false;
        match &mut self.active {
            Active::Gpu(solver) => {
                solver.encode_steps(encoder, steps);
                self.frames_since_status += u64::from(steps);
                if self.frames_since_status >= STATUS_EVERY
                    && self.status.encode_copy(encoder, solver.status_buffer())
                {
                    self.frames_since_status = 0;
                }
            }
            Active::Cpu(solver, buffer) => {
                if let Err(error) = solver.step(steps) {
                    self.message = Some(error.to_string());
                    self.paused = true;
                }
                let positions = positions_to_vec4(&solver.read_state().positions);
                self.context
                    .queue
                    .write_buffer(buffer, 0, bytemuck::cast_slice(&positions));
            }
        }
    }

    /// After submission: asks for the status read-back and judges one that has arrived.
    pub fn after_submit(&mut self) {
        self.status.request();
        if let Some(bytes) = self.status.try_take(&self.context)
            && let Active::Gpu(solver) = &mut self.active
            && let Err(error) = solver.judge_status(&bytes)
        {
            self.message = Some(format!("{error} (press Reset)"));
            self.paused = true;
        }
    }

    /// Times one step's phases (waits for the GPU once; a user action, not part of the loop).
    /// Times one step phase by phase (force, accumulation, integration, collision).
    pub fn measure_phases(&mut self) {
        let measured = match &mut self.active {
            Active::Gpu(solver) => solver.step_timed().map_err(|e| e.to_string()),
            Active::Cpu(solver, _) => solver
                .step_phased()
                .map(|times| (times, TimingSource::WallClock))
                .map_err(|e| e.to_string()),
        };
        match measured {
            Ok(times) => self.phases = Some(times),
            Err(error) => self.message = Some(error),
        }
    }
}

fn build(
    context: &Arc<GpuContext>,
    choice: Choice,
    model: &Model,
    params: &SimParams,
) -> anyhow::Result<Active> {
    Ok(match choice {
        Choice::Gpu(method) => Active::Gpu(Box::new(GpuSolver::new(
            Arc::clone(context),
            model,
            params,
            method,
        )?)),
        Choice::Cpu(method) => {
            let options = CpuOptions {
                method,
                ..Default::default()
            };
            let buffer = context.device.create_buffer(&wgpu::BufferDescriptor {
                label: Some("cpu positions upload"),
                size: 16 * model.vertex_count().max(1) as u64,
                usage: wgpu::BufferUsages::STORAGE | wgpu::BufferUsages::COPY_DST,
                mapped_at_creation: false,
            });
            Active::Cpu(Box::new(CpuSolver::new(model, params, options)?), buffer)
        }
    })
}
