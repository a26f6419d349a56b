//! The [`Simulation`] facade: one type over the reference, CPU and GPU solvers, with every call a
//! front end needs (build, step, read, drive live, time, draw).

use std::borrow::Cow;
use std::sync::Arc;

use glam::DVec3;
use hooke_core::collide::Collider;
use hooke_core::mesh::{Mesh, MeshError};
use hooke_core::reference::ReferenceSolver;
use hooke_core::scene::Scene;
use hooke_core::selfcollide::SelfCollision;
use hooke_core::stability::{StabilityLimit, stability_limit};
use hooke_core::tearing;
use hooke_core::{
    Control, MassModel, Material, Model, ModelError, ModelOptions, PhaseTimes, SimError, Snapshot,
    Solver, State, StiffnessModel, TimingSource,
};
use hooke_cpu::{CpuError, CpuMemory, CpuOptions, CpuSolver, Method};
use hooke_gpu::gpu;
use hooke_gpu::render::ClothBuffers;
use hooke_gpu::wgpu;
use hooke_gpu::{
    Accumulation, GpuContext, GpuError, GpuMemory, GpuMethod, GpuSolver, positions_to_vec4,
};

/// Which solver a [`Simulation`] runs.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum SolverChoice {
    /// float64, single-threaded: slow and exact, the oracle.
    Reference,
    /// float32, multithreaded, SIMD.
    Cpu(CpuOptions),
    /// float32 on the GPU, state resident in GPU buffers.
    Gpu(GpuMethod),
}

impl SolverChoice {
    /// `"reference"`, `"cpu gather"`, `"gpu scatter/incidence"`...
    pub fn name(&self) -> String {
        match self {
            Self::Reference => "reference".to_owned(),
            Self::Cpu(options) => format!("cpu {}", options.method.name()),
            Self::Gpu(method) => format!("gpu {}", method.name()),
        }
    }

    /// The solver named as on the command line: `backend` is `"reference"`, `"cpu"` or `"gpu"`;
    /// `method` `"gather"` or `"scatter"` (default: gather on the CPU, scatter on the GPU);
    /// `accumulation` one of GPU scatter's (default `"incidence"`); `threads` the CPU's workers
    /// (default: one per core). Front ends that take names (Python, the browser) use this.
    pub fn from_names(
        backend: &str,
        method: Option<&str>,
        accumulation: Option<&str>,
        threads: Option<usize>,
    ) -> Result<Self, String> {
        let unknown = |what: &str, found: &str, expected: &str| {
            format!("unknown {what} '{found}' (expected {expected})")
        };
        let gather = match method {
            None => None,
            Some("gather") => Some(true),
            Some("scatter") => Some(false),
            Some(other) => return Err(unknown("method", other, "gather or scatter")),
        };
        let accumulation = match accumulation {
            None => Accumulation::Incidence,
            Some(name) => Accumulation::from_name(name).ok_or_else(|| {
                let names: Vec<&str> = Accumulation::ALL.iter().map(|a| a.name()).collect();
                unknown("accumulation", name, &names.join(", "))
            })?,
        };
        if threads == Some(0) {
            return Err("threads must be at least 1".to_owned());
        }
        match backend {
            "reference" => Ok(Self::Reference),
            "cpu" => Ok(Self::Cpu(CpuOptions {
                method: if gather.unwrap_or(true) {
                    Method::Gather
                } else {
                    Method::Scatter
                },
                threads,
                ..Default::default()
            })),
            "gpu" => Ok(Self::Gpu(if gather.unwrap_or(false) {
                GpuMethod::Gather
            } else {
                GpuMethod::Scatter(accumulation)
            })),
            other => Err(unknown("backend", other, "reference, cpu or gpu")),
        }
    }
}

/// A simulation could not be built or changed.
#[derive(Debug, thiserror::Error)]
pub enum EngineError {
    #[error("starting the cpu solver: {0}")]
    Cpu(#[from] CpuError),
    #[error("starting the gpu solver: {0}")]
    Gpu(#[from] GpuError),
    #[error(transparent)]
    Mesh(#[from] MeshError),
    #[error(transparent)]
    Model(#[from] ModelError),
    #[error(transparent)]
    Simulation(#[from] SimError),
    #[error("the new model has {given} vertices, the running one {running}")]
    VertexCountChanged { given: usize, running: usize },
}

/// A mesh and material given as arrays, for [`model_from_arrays`].
#[derive(Clone, Debug)]
pub struct Arrays<'a> {
    /// Vertex positions, m.
    pub vertices: &'a [[f64; 3]],
    /// Triangles as vertex indices; every unique edge becomes a spring.
    pub triangles: &'a [[u32; 3]],
    /// Vertices held in place.
    pub pins: &'a [u32],
    pub stiffness: StiffnessModel,
    pub mass: MassModel,
}

/// A model from arrays, checked as a mesh file is (indices in range, no degenerate triangles).
pub fn model_from_arrays(arrays: &Arrays<'_>) -> Result<Model, EngineError> {
    let mesh = Mesh {
        positions: arrays
            .vertices
            .iter()
            .map(|v| DVec3::from_array(*v))
            .collect(),
        triangles: arrays.triangles.to_vec(),
        ..Mesh::default()
    };
    mesh.validate("arrays")?;
    let options = ModelOptions {
        stiffness: arrays.stiffness,
        mass: arrays.mass,
        rest_length_scale: 1.0,
        pinned: arrays.pins.to_vec(),
    };
    Ok(Model::from_mesh(&mesh, &options)?)
}

/// Bytes a solver holds, by role.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum MemoryReport {
    /// The reference keeps f64 state and a force buffer; not a figure worth comparing.
    Reference,
    Cpu(CpuMemory),
    Gpu(GpuMemory),
}

enum Engine {
    Reference(Box<ReferenceSolver>),
    /// With the buffers the positions and broken springs are uploaded into for drawing.
    Cpu(Box<CpuSolver>, Uploads),
    Gpu(Box<GpuSolver>),
}

/// What a CPU simulation uploads for drawing, each buffer created on first use.
#[derive(Default)]
struct Uploads {
    positions: Option<wgpu::Buffer>,
    /// The broken flags and how many were set when they were uploaded.
    broken: Option<(wgpu::Buffer, usize)>,
}

impl Engine {
    fn solver(&self) -> &dyn Solver {
        match self {
            Engine::Reference(s) => s.as_ref(),
            Engine::Cpu(s, _) => s.as_ref(),
            Engine::Gpu(s) => s.as_ref(),
        }
    }

    fn solver_mut(&mut self) -> &mut dyn Solver {
        match self {
            Engine::Reference(s) => s.as_mut(),
            Engine::Cpu(s, _) => s.as_mut(),
            Engine::Gpu(s) => s.as_mut(),
        }
    }
}

/// A model and the solver that advances it. Every front end (the CLI, the viewer, Python, the
/// browser) drives hooke through this type.
pub struct Simulation {
    model: Model,
    material: Material,
    control: Control,
    self_collision: Option<SelfCollision>,
    choice: SolverChoice,
    /// The GPU the solver runs on, or that positions are uploaded to for drawing.
    gpu: Option<Arc<GpuContext>>,
    engine: Engine,
}

impl std::fmt::Debug for Simulation {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str(&self.describe())
    }
}

impl Simulation {
    /// A simulation of `model` under `material` on the chosen solver, at rest at the model's
    /// initial positions. A GPU solver uses `gpu`, or opens the default adapter when it is
    /// `None`; a CPU one uses `gpu` only to upload positions for drawing.
    pub fn new(
        model: &Model,
        material: &Material,
        choice: SolverChoice,
        gpu: Option<Arc<GpuContext>>,
    ) -> Result<Self, EngineError> {
        let gpu = match (choice, gpu) {
            (SolverChoice::Gpu(_), None) => Some(GpuContext::new()?),
            (_, gpu) => gpu,
        };
        let engine = build(model, material, choice, gpu.as_ref())?;
        Ok(Self {
            model: model.clone(),
            material: *material,
            control: Control::default(),
            self_collision: model.collision.self_collision,
            choice,
            gpu,
            engine,
        })
    }

    /// A simulation of a built scene, driven by the scene's own control (wind, forces, drags).
    pub fn from_scene(
        scene: &Scene,
        choice: SolverChoice,
        gpu: Option<Arc<GpuContext>>,
    ) -> Result<Self, EngineError> {
        let mut simulation = Self::new(&scene.model, &scene.material, choice, gpu)?;
        simulation.set_control(scene.control.clone())?;
        Ok(simulation)
    }

    fn solver(&self) -> &dyn Solver {
        self.engine.solver()
    }

    fn solver_mut(&mut self) -> &mut dyn Solver {
        self.engine.solver_mut()
    }

    /// A short description such as `"cpu scatter (f32, 2 threads)"`.
    pub fn describe(&self) -> String {
        self.solver().describe()
    }

    pub fn choice(&self) -> SolverChoice {
        self.choice
    }

    /// The model, its collision set-up included (its stiffnesses before the material's scale).
    pub fn model(&self) -> &Model {
        &self.model
    }

    pub fn material(&self) -> &Material {
        &self.material
    }

    pub fn control(&self) -> &Control {
        &self.control
    }

    pub fn self_collision(&self) -> Option<SelfCollision> {
        self.self_collision
    }

    /// Lets a CPU or reference simulation draw on `gpu` (a GPU simulation draws on its own).
    pub fn draw_with(&mut self, gpu: Arc<GpuContext>) {
        if self.gpu.is_none() {
            self.gpu = Some(gpu);
        }
    }

    /// The GPU this simulation runs on or draws with.
    pub fn gpu(&self) -> Option<&Arc<GpuContext>> {
        self.gpu.as_ref()
    }

    /// Advances `steps` time steps.
    pub fn step(&mut self, steps: u32) -> Result<(), SimError> {
        self.solver_mut().step(steps)
    }

    /// One step with each phase timed; results equal [`Simulation::step`]'s.
    pub fn step_timed(&mut self) -> Result<(PhaseTimes, TimingSource), SimError> {
        self.solver_mut().step_timed()
    }

    /// `steps` steps with each phase timed, a [`PhaseTimes`] a step ([`Solver::steps_timed`]);
    /// results equal [`Simulation::step`]'s.
    pub fn steps_timed(&mut self, steps: u32) -> Result<(Vec<PhaseTimes>, TimingSource), SimError> {
        self.solver_mut().steps_timed(steps)
    }

    pub fn steps_taken(&self) -> u64 {
        self.solver().steps_taken()
    }

    /// The simulated time, s (steps times the current dt).
    pub fn time(&self) -> f64 {
        self.steps_taken() as f64 * self.material.dt
    }

    /// The current state (a read-back on the GPU).
    pub fn state(&self) -> Result<State, SimError> {
        self.solver().read_state()
    }

    /// Replaces the state (positions and previous positions).
    pub fn set_state(&mut self, state: &State) {
        self.solver_mut().write_state(state);
    }

    /// The colliders where they are now (a read-back on the GPU when there are dynamic balls).
    pub fn colliders(&self) -> Result<Vec<Collider>, SimError> {
        self.solver().colliders()
    }

    /// Takes new per-step inputs: written into the solver's existing buffers, nothing rebuilt.
    pub fn set_control(&mut self, control: Control) -> Result<(), SimError> {
        self.solver_mut().set_control(&control)?;
        self.control = control;
        Ok(())
    }

    /// Takes a new dt, damping, gravity or stiffness scale, in place: nothing rebuilt, nothing
    /// read back.
    pub fn set_material(&mut self, material: Material) -> Result<(), SimError> {
        self.solver_mut().set_material(&material)?;
        self.material = material;
        Ok(())
    }

    /// Turns self-collision on or off (a change of set-up: the GPU builds its pass here).
    pub fn set_self_collision(&mut self, config: Option<SelfCollision>) -> Result<(), SimError> {
        self.solver_mut().set_self_collision(config)?;
        self.self_collision = config;
        Ok(())
    }

    /// The state, colliders and step counter, to continue from later.
    pub fn snapshot(&self) -> Result<Snapshot, SimError> {
        self.solver().snapshot()
    }

    /// Continues from a snapshot of this model.
    pub fn restore(&mut self, snapshot: &Snapshot) -> Result<(), SimError> {
        self.solver_mut().restore(snapshot)
    }

    /// Moves the running simulation onto another solver, carrying on where it is.
    pub fn switch_solver(&mut self, choice: SolverChoice) -> Result<(), EngineError> {
        self.rebuild(self.model.clone(), choice)
    }

    /// Carries the run on with `model` in place of the running one: the same vertices, other
    /// springs or stiffnesses (the viewer's bending control). The solver is built anew.
    pub fn set_model(&mut self, model: Model) -> Result<(), EngineError> {
        if model.vertex_count() != self.model.vertex_count() {
            return Err(EngineError::VertexCountChanged {
                given: model.vertex_count(),
                running: self.model.vertex_count(),
            });
        }
        self.rebuild(model, self.choice)
    }

    /// Pins `vertex` where it is, or at `at` (at rest there), as a scene pin: it stays until
    /// [`Simulation::unpin`]. The solver is built anew, carrying the run on.
    pub fn pin(&mut self, vertex: u32, at: Option<DVec3>) -> Result<(), EngineError> {
        let v = self.vertex_index(vertex)?;
        let mut snapshot = self.snapshot()?;
        if let Some(at) = at {
            snapshot.state.positions[v] = at;
            snapshot.state.previous_positions[v] = at;
        }
        let mut model = self.model.clone();
        model.pinned[v] = true;
        self.rebuild_from(model, self.choice, &snapshot)
    }

    /// Lets a pinned vertex (a scene pin too) move again, from rest where it is.
    pub fn unpin(&mut self, vertex: u32) -> Result<(), EngineError> {
        let v = self.vertex_index(vertex)?;
        let mut model = self.model.clone();
        model.pinned[v] = false;
        self.set_model(model)
    }

    fn vertex_index(&self, vertex: u32) -> Result<usize, EngineError> {
        let count = self.model.vertex_count();
        if (vertex as usize) < count {
            Ok(vertex as usize)
        } else {
            Err(EngineError::Model(ModelError::PinOutOfRange {
                index: vertex,
                vertex_count: count,
            }))
        }
    }

    /// A new solver of `model` on `choice`, continuing from where this one is.
    fn rebuild(&mut self, model: Model, choice: SolverChoice) -> Result<(), EngineError> {
        let snapshot = self.snapshot()?;
        self.rebuild_from(model, choice, &snapshot)
    }

    /// A new solver of `model` on `choice`, continuing from `snapshot`.
    fn rebuild_from(
        &mut self,
        model: Model,
        choice: SolverChoice,
        snapshot: &Snapshot,
    ) -> Result<(), EngineError> {
        let gpu = match (choice, &self.gpu) {
            (SolverChoice::Gpu(_), None) => Some(GpuContext::new()?),
            (_, gpu) => gpu.clone(),
        };
        let mut engine = build(&model, &self.material, choice, gpu.as_ref())?;
        let solver = engine.solver_mut();
        solver.set_control(&self.control)?;
        solver.set_self_collision(self.self_collision)?;
        solver.restore(snapshot)?;
        self.engine = engine;
        self.model = model;
        self.choice = choice;
        self.gpu = gpu;
        Ok(())
    }

    /// The largest stable dt under the current damping and stiffness scale.
    pub fn stability_limit(&self) -> StabilityLimit {
        self.stability_limit_under(&self.material)
    }

    /// The largest stable dt under `material`'s damping and stiffness scale.
    pub fn stability_limit_under(&self, material: &Material) -> StabilityLimit {
        let scaled;
        let model = if material.stiffness_scale == 1.0 {
            &self.model
        } else {
            scaled = self.model.with_stiffness_scale(material.stiffness_scale);
            &scaled
        };
        stability_limit(model, material.damping)
    }

    /// The bytes the solver holds, by role.
    pub fn memory(&self) -> MemoryReport {
        match &self.engine {
            Engine::Reference(_) => MemoryReport::Reference,
            Engine::Cpu(s, _) => MemoryReport::Cpu(s.memory()),
            Engine::Gpu(s) => MemoryReport::Gpu(s.memory()),
        }
    }

    /// The CPU solver, for what only it offers (thread count, bandwidth floor).
    pub fn cpu_solver(&self) -> Option<&CpuSolver> {
        match &self.engine {
            Engine::Cpu(s, _) => Some(s),
            _ => None,
        }
    }

    /// The GPU solver, for what only it offers (wall-clock timing, status read-backs).
    pub fn gpu_solver_mut(&mut self) -> Option<&mut GpuSolver> {
        match &mut self.engine {
            Engine::Gpu(s) => Some(s),
            _ => None,
        }
    }

    /// Advances `steps` steps for a frame that draws: on the GPU they are recorded into
    /// `encoder` (nothing waits); on the CPU they run now and the positions are uploaded into
    /// [`Simulation::positions_buffer`].
    pub fn encode_frame(
        &mut self,
        encoder: &mut wgpu::CommandEncoder,
        steps: u32,
    ) -> Result<(), SimError> {
        let gpu = self.gpu.clone();
        match &mut self.engine {
            Engine::Gpu(solver) => {
                solver.encode_steps(encoder, steps);
                Ok(())
            }
            Engine::Cpu(solver, uploads) => {
                solver.step(steps)?;
                let state = solver.read_state()?;
                if let Some(context) = gpu.as_deref() {
                    uploads.positions(context, &state.positions);
                    if self.model.tearing.is_some() {
                        uploads.broken(context, solver);
                    }
                }
                Ok(())
            }
            Engine::Reference(solver) => {
                solver.step(steps)?;
                Ok(())
            }
        }
    }

    /// The `vec4`-per-vertex buffer to draw: the GPU solver's current positions, or the CPU
    /// positions uploaded by [`Simulation::encode_frame`].
    pub fn positions_buffer(&self) -> Option<&wgpu::Buffer> {
        match &self.engine {
            Engine::Gpu(solver) => Some(solver.current_positions()),
            Engine::Cpu(_, uploads) => uploads.positions.as_ref(),
            Engine::Reference(_) => None,
        }
    }

    /// What a renderer draws: [`Simulation::positions_buffer`] and, when springs can break,
    /// the broken flags (the GPU solver's own, or the CPU's uploaded by
    /// [`Simulation::encode_frame`]).
    pub fn cloth_buffers(&self) -> Option<ClothBuffers<'_>> {
        let broken_springs = match &self.engine {
            Engine::Gpu(solver) => solver.broken_springs_buffer(),
            Engine::Cpu(_, uploads) => uploads.broken.as_ref().map(|(b, _)| b),
            Engine::Reference(_) => None,
        };
        Some(ClothBuffers {
            positions: self.positions_buffer()?,
            broken_springs,
        })
    }

    /// The springs torn so far, in order (a read-back on the GPU).
    pub fn broken_springs(&self) -> Result<Vec<u32>, SimError> {
        self.solver().broken_springs()
    }

    /// The model as the solver steps it now: torn springs at zero stiffness. What energies,
    /// strains and health checks of the current state are measured on (a read-back of the
    /// broken flags on the GPU, none when nothing has torn).
    pub fn torn_model(&self) -> Result<Cow<'_, Model>, SimError> {
        let broken = self.broken_springs()?;
        if broken.is_empty() {
            return Ok(Cow::Borrowed(&self.model));
        }
        let flags = tearing::broken_flags(&broken, self.model.spring_count())?;
        Ok(Cow::Owned(self.model.with_springs_broken(&flags)))
    }

    /// Records copies of the GPU's dynamic ball places into a renderer's sphere buffer; on the
    /// CPU the renderer is given the colliders instead.
    pub fn copy_spheres(&self, encoder: &mut wgpu::CommandEncoder, target: &wgpu::Buffer) {
        if let Engine::Gpu(solver) = &self.engine {
            solver.copy_spheres(encoder, target);
        }
    }

    /// The colliders to draw this frame without waiting for the GPU: scripted ones placed by
    /// time (the GPU's dynamic balls come in by [`Simulation::copy_spheres`]).
    pub fn colliders_to_draw(&self) -> Vec<Collider> {
        match &self.engine {
            Engine::Gpu(_) => {
                hooke_core::collide::placed(&self.model.collision.colliders, self.time())
            }
            _ => self.colliders().unwrap_or_default(),
        }
    }
}

impl Uploads {
    /// Copies positions into the draw buffer, creating it on first use.
    fn positions(&mut self, context: &GpuContext, positions: &[DVec3]) {
        let buffer = self.positions.get_or_insert_with(|| {
            let bytes = 16 * positions.len() as u64;
            gpu::zeroed(
                context,
                "cpu positions upload",
                bytes,
                wgpu::BufferUsages::COPY_DST,
            )
        });
        context.queue.write_buffer(
            buffer,
            0,
            bytemuck::cast_slice(&positions_to_vec4(positions)),
        );
    }

    /// Copies the broken flags (one `u32` per spring) of `solver` when more have broken since
    /// the last upload (springs only ever break while stepping).
    fn broken(&mut self, context: &GpuContext, solver: &CpuSolver) {
        let count = solver.broken_count();
        if self.broken.as_ref().is_some_and(|(_, sent)| *sent == count) {
            return;
        }
        let flags = solver.broken_flags();
        let (buffer, sent) = self.broken.get_or_insert_with(|| {
            let bytes = 4 * flags.len() as u64;
            let usage = wgpu::BufferUsages::COPY_DST;
            let buffer = gpu::zeroed(context, "cpu broken springs upload", bytes, usage);
            (buffer, usize::MAX)
        });
        let words: Vec<u32> = flags.iter().map(|b| u32::from(*b)).collect();
        context
            .queue
            .write_buffer(buffer, 0, bytemuck::cast_slice(&words));
        *sent = count;
    }
}

fn build(
    model: &Model,
    material: &Material,
    choice: SolverChoice,
    gpu: Option<&Arc<GpuContext>>,
) -> Result<Engine, EngineError> {
    Ok(match choice {
        SolverChoice::Reference => {
            Engine::Reference(Box::new(ReferenceSolver::new(model, material)))
        }
        SolverChoice::Cpu(options) => Engine::Cpu(
            Box::new(CpuSolver::new(model, material, options)?),
            Uploads::default(),
        ),
        SolverChoice::Gpu(method) => {
            let context = gpu
                .cloned()
                .ok_or_else(|| GpuError::Validation("no GPU context".into()))?;
            Engine::Gpu(Box::new(GpuSolver::new(context, model, material, method)?))
        }
    })
}
