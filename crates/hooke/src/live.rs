//! A simulation driven live by a front end (the viewer's window, the browser page): the solver
//! choice, the controls, the grabbed vertex, and status checks that never make a frame wait.
//!
//! The panel's values become a [`Control`] (drag, wind, pushes), a [`Material`] (stiffness,
//! damping, dt, gravity) and a self-collision set-up; [`LiveSimulation::apply`] sends only what
//! changed to the engine, which writes it into buffers it has: a drag or a slider creates no
//! pipeline and reads nothing back.

use std::sync::Arc;

use glam::{DVec3, Vec3};
use hooke_core::collide::Collider;
use hooke_core::scene::Scene;
use hooke_core::selfcollide::SelfCollision;
use hooke_core::tearing::Tearing;
use hooke_core::{BallPush, Control, Drag, Material, Model, PhaseTimes, TimingSource, Wind};
use hooke_cpu::{CpuOptions, Method};
use hooke_gpu::render::{AsyncReadback, ClothBuffers};
use hooke_gpu::wgpu;
use hooke_gpu::{Accumulation, GpuContext, GpuMethod};

use crate::{EngineError, Simulation, SolverChoice};

/// Which solver runs.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Choice {
    Gpu(GpuMethod),
    Cpu(Method),
}

impl Choice {
    /// The live choice for a solver; the reference is not one (it has no GPU buffer to draw).
    pub fn from_solver(choice: SolverChoice) -> Option<Self> {
        match choice {
            SolverChoice::Reference => None,
            SolverChoice::Cpu(options) => Some(Choice::Cpu(options.method)),
            SolverChoice::Gpu(method) => Some(Choice::Gpu(method)),
        }
    }

    pub fn label(self) -> String {
        match self {
            Self::Gpu(m) => format!("gpu {}", m.name()),
            Self::Cpu(m) => format!("cpu {} (uploads positions each frame)", m.name()),
        }
    }

    pub fn solver(self) -> SolverChoice {
        match self {
            Self::Gpu(method) => SolverChoice::Gpu(method),
            Self::Cpu(method) => SolverChoice::Cpu(CpuOptions {
                method,
                ..Default::default()
            }),
        }
    }
}

/// The GPU methods `context`'s adapter can run (float atomics and float32 blending are
/// optional features; WebGPU has no float atomics at all).
pub fn gpu_methods(context: &GpuContext) -> Vec<GpuMethod> {
    GpuMethod::all()
        .into_iter()
        .filter(|m| match m {
            GpuMethod::Scatter(Accumulation::AtomicF32) => {
                context.has(wgpu::Features::SHADER_FLOAT32_ATOMIC)
            }
            GpuMethod::Scatter(Accumulation::BlendR32f) => {
                context.has(wgpu::Features::FLOAT32_BLENDABLE)
            }
            _ => true,
        })
        .collect()
}

/// The scene's tearing threshold (1.5 when it does not tear: the panel shows none then).
fn scene_max_stretch(scene: &Scene) -> f64 {
    scene.model.tearing.map_or(1.5, |t| t.max_stretch)
}

/// Steps between non-blocking status checks of the GPU solver.
const STATUS_EVERY: u64 = 30;

#[derive(Debug)]
pub struct LiveSimulation {
    context: Arc<GpuContext>,
    scene: Scene,
    engine: Simulation,
    pub choice: Choice,
    pub choices: Vec<Choice>,
    pub stiffness_scale: f64,
    /// The scene's bending springs' stiffness times this (0: off).
    pub bending_scale: f64,
    /// The bending scale of the running model.
    running_bending_scale: f64,
    /// Each bending spring's own damping, N s/m.
    pub bending_damping: f64,
    /// The bending damping of the running model.
    running_bending_damping: f64,
    /// Springs break past this many times their rest length (used when the scene tears).
    pub max_stretch: f64,
    /// The tearing threshold of the running model.
    running_max_stretch: f64,
    /// Counts the changes to which vertices are pinned, for whatever draws the pins.
    pins_changed: u64,
    /// Vertices pinned since the start beyond the scene's own (counted when pins change, not
    /// on every frame the panel shows it).
    added_pins: usize,
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
    /// The GPU's count of broken springs, read back with the status.
    torn: AsyncReadback,
    /// The count it last delivered.
    gpu_broken_springs: usize,
    frames_since_status: u64,
}

impl LiveSimulation {
    pub fn new(
        context: Arc<GpuContext>,
        scene: Scene,
        choice: Choice,
    ) -> Result<Self, EngineError> {
        let choices: Vec<Choice> = gpu_methods(&context)
            .into_iter()
            .map(Choice::Gpu)
            .chain(Method::ALL.map(Choice::Cpu))
            .collect();
        let wind = scene.control.wind;
        let (heading, speed) = wind.map_or((0.0, 3.0), |w| {
            (
                w.velocity.z.atan2(w.velocity.x).to_degrees(),
                w.velocity.length(),
            )
        });
        let engine = Simulation::from_scene(&scene, choice.solver(), Some(Arc::clone(&context)))?;
        let status = AsyncReadback::new(
            &context,
            "status read-back",
            std::mem::size_of::<hooke_gpu::layout::GpuStatus>() as u64,
        );
        let torn = AsyncReadback::new(&context, "broken spring count read-back", 16);
        let colliders = &scene.model.collision.colliders;
        Ok(Self {
            max_stable_dt: scene.max_stable_dt,
            dt_fraction: (scene.material.dt / scene.max_stable_dt).min(1.0),
            damping: scene.material.damping,
            gravity_y: scene.material.gravity.y,
            wind_enabled: wind.is_some(),
            wind_heading_degrees: heading,
            wind_speed: speed,
            wind_coefficient: wind.map_or(0.5, |w| w.coefficient),
            self_collision_enabled: scene.model.collision.self_collision.is_some(),
            selected_ball: colliders.iter().position(|c| c.dynamics.is_some()),
            // Three times the heaviest ball's weight: enough to roll it into the cloth.
            push_newtons: 3.0
                * 9.81
                * colliders
                    .iter()
                    .filter_map(|c| c.dynamics.map(|d| d.mass))
                    .fold(0.0, f64::max),
            push_direction: DVec3::ZERO,
            self_collision: scene
                .model
                .collision
                .self_collision
                .unwrap_or_else(|| SelfCollision::for_model(&scene.model)),
            stiffness_scale: 1.0,
            bending_scale: 1.0,
            running_bending_scale: 1.0,
            bending_damping: scene.model.bending_damping,
            running_bending_damping: scene.model.bending_damping,
            max_stretch: scene_max_stretch(&scene),
            running_max_stretch: scene_max_stretch(&scene),
            pins_changed: 0,
            added_pins: 0,
            steps_per_frame: 10,
            scene,
            engine,
            choice,
            choices,
            context,
            paused: false,
            step_once: false,
            grab: None,
            message: None,
            phases: None,
            status,
            torn,
            gpu_broken_springs: 0,
            frames_since_status: 0,
        })
    }

    pub fn scene_name(&self) -> &str {
        &self.scene.name
    }

    pub fn model(&self) -> &Model {
        self.engine.model()
    }

    pub fn dt(&self) -> f64 {
        self.dt_fraction * self.max_stable_dt
    }

    pub fn steps_taken(&self) -> u64 {
        self.engine.steps_taken()
    }

    /// The colliders to draw this frame, without waiting for the GPU.
    pub fn colliders_to_draw(&self) -> Vec<Collider> {
        self.engine.colliders_to_draw()
    }

    /// Records copies of the GPU solver's ball places into the renderer's sphere buffer.
    pub fn copy_spheres(&self, encoder: &mut wgpu::CommandEncoder, target: &wgpu::Buffer) {
        self.engine.copy_spheres(encoder, target);
    }

    /// The buffers the renderer draws: the GPU solver's own, or the CPU uploads.
    pub fn cloth(&self) -> Option<ClothBuffers<'_>> {
        self.engine.cloth_buffers()
    }

    /// The wind the controls describe.
    pub fn wind(&self) -> Option<Wind> {
        let heading = self.wind_heading_degrees.to_radians();
        self.wind_enabled.then(|| Wind {
            velocity: DVec3::new(heading.cos(), 0.0, heading.sin()) * self.wind_speed,
            coefficient: self.wind_coefficient,
        })
    }

    /// The per-step inputs the controls describe.
    pub fn control(&self) -> Control {
        let mass = |v: u32| self.model().masses[v as usize];
        let dt = self.dt();
        Control {
            wind: self.wind(),
            point_forces: self.scene.control.point_forces.clone(),
            drags: self
                .grab
                .map(|(vertex, target)| Drag {
                    vertices: vec![vertex],
                    target: target.as_dvec3(),
                    // Stiff enough to lead the cloth, soft enough to stay stable: it adds a fifth
                    // of the stability budget to the grabbed vertex.
                    stiffness: 0.2 * mass(vertex) / (dt * dt),
                })
                .into_iter()
                .chain(self.scene.control.drags.iter().cloned())
                .collect(),
            ball_pushes: self
                .selected_ball
                .filter(|_| self.push_direction != DVec3::ZERO)
                .map(|collider| BallPush {
                    collider,
                    force: self.push_direction * self.push_newtons,
                })
                .into_iter()
                .collect(),
        }
    }

    /// The material the controls describe; `max_stable_dt` follows its stiffness and damping
    /// (recomputed only when they change: it visits every vertex, and a drag calls this on
    /// every mouse move).
    fn material(&mut self) -> Material {
        let running = *self.engine.material();
        let material = Material {
            damping: self.damping,
            gravity: DVec3::new(0.0, self.gravity_y, 0.0),
            stiffness_scale: self.stiffness_scale,
            ..running
        };
        if (material.damping, material.stiffness_scale)
            != (running.damping, running.stiffness_scale)
        {
            self.max_stable_dt = self.engine.stability_limit_under(&material).max_dt;
        }
        Material {
            dt: self.dt(),
            ..material
        }
    }

    /// Sends what the controls changed to the engine, in place: the material, the control,
    /// the self-collision set-up (only that builds anything: the GPU's self-collision pass).
    pub fn apply(&mut self) {
        let wanted = (self.bending_scale, self.bending_damping, self.max_stretch);
        let running = (
            self.running_bending_scale,
            self.running_bending_damping,
            self.running_max_stretch,
        );
        if wanted != running {
            // Other stiffnesses, dampers or tearing threshold: the solver is built anew,
            // carrying the run on (the pins added since the start, the springs torn so far).
            let mut model = self.scene.model.with_bending_scale(self.bending_scale);
            model.pinned.clone_from(&self.model().pinned);
            model.bending_damping = self.bending_damping;
            if model.tearing.is_some() {
                model.tearing = Some(Tearing {
                    max_stretch: self.max_stretch,
                });
            }
            (
                self.running_bending_scale,
                self.running_bending_damping,
                self.running_max_stretch,
            ) = wanted;
            if let Err(error) = self.engine.set_model(model) {
                self.message = Some(error.to_string());
                self.paused = true;
                return;
            }
            let running = *self.engine.material();
            self.max_stable_dt = self.engine.stability_limit_under(&running).max_dt;
        }
        let mut result = Ok(());
        let material = self.material();
        let control = self.control();
        let self_collision = self.self_collision_enabled.then_some(self.self_collision);
        if material != *self.engine.material() {
            result = result.and(self.engine.set_material(material));
        }
        if control != *self.engine.control() {
            result = result.and(self.engine.set_control(control));
        }
        if self_collision != self.engine.self_collision() {
            result = result.and(self.engine.set_self_collision(self_collision));
        }
        if let Err(error) = result {
            self.message = Some(error.to_string());
            self.paused = true;
        }
    }

    /// Pins the vertex of `grab` (the grabbed vertex and where the cursor holds it) there, at
    /// rest: the viewer's `p` key lets go of the cloth and leaves it hanging from that point.
    pub fn pin_grabbed(&mut self, grab: Option<(u32, Vec3)>) {
        let Some((vertex, target)) = grab else {
            return;
        };
        match self.engine.pin(vertex, Some(target.as_dvec3())) {
            Ok(()) => self.pins_were_changed(),
            Err(error) => self.message = Some(error.to_string()),
        }
    }

    /// Notes that the running model's pins changed.
    fn pins_were_changed(&mut self) {
        self.pins_changed += 1;
        let (now, scene) = (&self.model().pinned, &self.scene.model.pinned);
        self.added_pins = now.iter().zip(scene).filter(|(a, b)| **a && !**b).count();
    }

    /// How many times the set of pinned vertices has changed since the start: a renderer
    /// redraws its pin markers when this moves.
    pub fn pins_changed(&self) -> u64 {
        self.pins_changed
    }

    /// Lets go of every vertex pinned since the start (the scene's own pins stay).
    pub fn unpin_added(&mut self) {
        let mut model = self.model().clone();
        model.pinned.clone_from(&self.scene.model.pinned);
        if model.pinned != self.model().pinned {
            match self.engine.set_model(model) {
                Ok(()) => self.pins_were_changed(),
                Err(error) => self.message = Some(error.to_string()),
            }
        }
    }

    /// Vertices pinned since the start, beyond the scene's own.
    pub fn added_pins(&self) -> usize {
        self.added_pins
    }

    /// Moves the running simulation onto another solver (a user action: it reads the state
    /// back once).
    pub fn switch(&mut self, choice: Choice) {
        match self.engine.switch_solver(choice.solver()) {
            Ok(()) => {
                self.choice = choice;
                self.message = None;
            }
            Err(error) => self.message = Some(format!("{}: {error:#}", choice.label())),
        }
    }

    /// Starts the scene again on another solver: where the state cannot be read back while the
    /// page waits (a browser), this is how the method changes.
    pub fn restart_on(&mut self, choice: Choice) {
        let previous = std::mem::replace(&mut self.choice, choice);
        self.reset();
        if self.message.is_some() {
            self.choice = previous;
        }
    }

    /// Starts the scene again on the current solver, with the controls as they are.
    pub fn reset(&mut self) {
        match Simulation::from_scene(
            &self.scene,
            self.choice.solver(),
            Some(Arc::clone(&self.context)),
        ) {
            Ok(engine) => {
                self.engine = engine;
                self.gpu_broken_springs = 0;
                self.running_bending_scale = 1.0;
                self.running_bending_damping = self.scene.model.bending_damping;
                self.running_max_stretch = scene_max_stretch(&self.scene);
                self.pins_were_changed();
                self.message = None;
                self.apply();
            }
            Err(error) => self.message = Some(format!("{}: {error:#}", self.choice.label())),
        }
        self.paused = false;
    }

    /// How many springs have torn: counted now on the CPU, as of the last status read-back on
    /// the GPU (which never waits for it).
    pub fn broken_springs(&self) -> usize {
        match self.engine.cpu_solver() {
            Some(cpu) => cpu.broken_count(),
            None => self.gpu_broken_springs,
        }
    }

    /// Dynamic balls the panel and keys can push, as collider indices.
    pub fn balls(&self) -> Vec<usize> {
        let colliders = &self.model().collision.colliders;
        (0..colliders.len())
            .filter(|&k| colliders[k].dynamics.is_some())
            .collect()
    }

    /// Pushes the selected ball along `direction` (unit or zero) with `push_newtons`.
    pub fn push(&mut self, direction: DVec3) {
        if direction != self.push_direction {
            self.push_direction = direction;
            self.apply();
        }
    }

    /// Records this frame's steps. GPU steps go into `encoder`; CPU steps run now and their
    /// positions are uploaded for drawing.
    pub fn encode_frame(&mut self, encoder: &mut wgpu::CommandEncoder) {
        let steps = if self.paused && !self.step_once {
            0
        } else if self.step_once {
            1
        } else {
            self.steps_per_frame
        };
        self.step_once = false;
        self.encode_steps(encoder, steps);
    }

    /// Records `steps` steps into `encoder` whatever the pause state (a scripted run's exact
    /// count), with the status check every [`STATUS_EVERY`] steps.
    pub fn encode_steps(&mut self, encoder: &mut wgpu::CommandEncoder, steps: u32) {
        if let Err(error) = self.engine.encode_frame(encoder, steps) {
            self.message = Some(error.to_string());
            self.paused = true;
        }
        if let Some(solver) = self.engine.gpu_solver_mut() {
            self.frames_since_status += u64::from(steps);
            if self.frames_since_status >= STATUS_EVERY
                && self.status.encode_copy(encoder, solver.status_buffer())
            {
                self.frames_since_status = 0;
                if let Some(count) = solver.broken_count_buffer() {
                    self.torn.encode_copy(encoder, count);
                }
            }
        }
    }

    /// After submission: asks for the status read-back and judges one that has arrived.
    pub fn after_submit(&mut self) {
        self.status.request();
        self.torn.request();
        if let Some(bytes) = self.torn.try_take(&self.context) {
            self.gpu_broken_springs = bytemuck::pod_read_unaligned::<u32>(&bytes[..4]) as usize;
        }
        if let Some(bytes) = self.status.try_take(&self.context)
            && let Some(solver) = self.engine.gpu_solver_mut()
            && let Err(error) = solver.judge_status(&bytes)
        {
            self.message = Some(format!("{error} (press Reset)"));
            self.paused = true;
        }
    }

    /// Times one step phase by phase (force, accumulation, integration, collision); waits for
    /// the GPU once: a user action, not part of the loop.
    pub fn measure_phases(&mut self) {
        match self.engine.step_timed() {
            Ok(times) => self.phases = Some(times),
            Err(error) => self.message = Some(error.to_string()),
        }
    }
}
