//! `hooke.Simulation`: a [`hooke::Simulation`] behind a lock, so that `step` can release the GIL
//! while other Python threads run.

use std::path::{Path, PathBuf};
use std::sync::{Mutex, MutexGuard};

use glam::DVec3;
use hooke::{OffscreenRun, SolverChoice};
use hooke_core::mesh::{Mesh, TextureCoordinates};
use hooke_core::scene::SceneFile;
use hooke_core::{BallPush, Control, Drag, PointForce, State, Wind};
use numpy::{PyArray2, PyArrayMethods};
use pyo3::prelude::*;
use pyo3::types::PyDict;

use crate::convert::{self, PerItem};
use crate::errors::{HookeError, OrRaise, input};

/// A saved state of a simulation (positions, previous positions, balls, step counter, torn
/// springs), to `restore` later. Opaque; made by `Simulation.snapshot()`.
#[pyclass(module = "hooke._native", name = "Snapshot", frozen)]
#[derive(Debug)]
pub struct Snapshot {
    inner: hooke::Snapshot,
}

#[pymethods]
impl Snapshot {
    /// The step counter when the snapshot was taken.
    #[getter]
    fn steps_taken(&self) -> u64 {
        self.inner.steps_taken
    }

    /// How many springs had torn when the snapshot was taken.
    #[getter]
    fn broken_spring_count(&self) -> usize {
        self.inner.broken_springs.len()
    }
}

/// The simulation, on its own or inside the offscreen renderer once something was drawn.
enum Holder {
    Bare(Box<hooke::Simulation>),
    Drawing(Box<OffscreenRun>),
}

impl Holder {
    fn simulation(&mut self) -> &mut hooke::Simulation {
        match self {
            Holder::Bare(simulation) => simulation,
            Holder::Drawing(run) => &mut run.simulation,
        }
    }
}

/// A mass-spring simulation on the float64 reference, the CPU or the GPU solver.
#[pyclass(module = "hooke._native", name = "Simulation")]
pub struct Simulation {
    holder: Mutex<Option<Holder>>,
    name: String,
    /// The mesh's texture coordinates, for the frames a `FrameWriter` writes.
    uvs: Option<TextureCoordinates>,
}

impl std::fmt::Debug for Simulation {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        write!(f, "Simulation({})", self.name)
    }
}

/// The solver chosen by name, and a GPU context when it needs one.
fn solver_choice(
    backend: &str,
    method: Option<&str>,
    accumulation: Option<&str>,
    threads: Option<usize>,
) -> PyResult<SolverChoice> {
    SolverChoice::from_names(backend, method, accumulation, threads).map_err(input)
}

fn open(scene: &hooke_core::scene::Scene, choice: SolverChoice) -> PyResult<Simulation> {
    let gpu = match choice {
        SolverChoice::Gpu(_) => Some(hooke_gpu::GpuContext::new().or_raise()?),
        _ => None,
    };
    let simulation = hooke::Simulation::from_scene(scene, choice, gpu).or_raise()?;
    Ok(Simulation {
        holder: Mutex::new(Some(Holder::Bare(Box::new(simulation)))),
        name: scene.name.clone(),
        uvs: scene.mesh.uvs.clone(),
    })
}

fn vector(v: [f64; 3], what: &str) -> PyResult<DVec3> {
    let v = DVec3::from_array(v);
    if v.is_finite() {
        Ok(v)
    } else {
        Err(input(format!("{what} must be finite, found {v}")))
    }
}

#[pymethods]
impl Simulation {
    /// A simulation of the scene file at `path` (TOML), on the solver named as on the CLI.
    #[staticmethod]
    #[pyo3(signature = (path, *, backend = "cpu", method = None, accumulation = None, threads = None, allow_unstable = false))]
    fn from_scene(
        path: PathBuf,
        backend: &str,
        method: Option<&str>,
        accumulation: Option<&str>,
        threads: Option<usize>,
        allow_unstable: bool,
    ) -> PyResult<Self> {
        let choice = solver_choice(backend, method, accumulation, threads)?;
        let scene = SceneFile::load(&path)
            .and_then(|file| file.build(&path, allow_unstable))
            .or_raise()?;
        open(&scene, choice)
    }

    /// A simulation of a mesh given as arrays, with the settings of a scene file as keywords
    /// (checked by the same code, with the same messages). `stiffness` (N/m) is a number or
    /// one per spring (in `springs(triangles)` order); give exactly one of `mass_total` (kg),
    /// `mass_per_vertex` (kg, a number or one per vertex) or `area_density` (kg/m^2).
    /// `colliders`, `wind`, `self_collision`, `bending`, `handles` and `tearing` are dicts (a
    /// list of them for colliders and handles) with the keys of the scene file's `[[collider]]`,
    /// `[wind]`, `[self_collision]`, `[bending]`, `[[handle]]` and `[tearing]`. `uvs`, an
    /// `(N, 2)` array of texture coordinates per vertex, goes into OBJ and USD frames.
    #[staticmethod]
    #[pyo3(signature = (
        vertices, triangles, *, stiffness, mass_total = None, mass_per_vertex = None,
        area_density = None, stiffness_model = "uniform", damping = 0.0, pins = None,
        select = None, dt = None, gravity = [0.0, -9.81, 0.0], wind = None, thickness = 0.0,
        colliders = None, self_collision = None, bending = None, handles = None, tearing = None,
        uvs = None,
        backend = "cpu",
        method = None,
        accumulation = None, threads = None, allow_unstable = false
    ))]
    #[allow(clippy::too_many_arguments)] // the keyword arguments of a Python call
    fn from_arrays(
        vertices: &Bound<'_, PyAny>,
        triangles: &Bound<'_, PyAny>,
        stiffness: &Bound<'_, PyAny>,
        mass_total: Option<f64>,
        mass_per_vertex: Option<&Bound<'_, PyAny>>,
        area_density: Option<f64>,
        stiffness_model: &str,
        damping: f64,
        pins: Option<Vec<u32>>,
        select: Option<Vec<String>>,
        dt: Option<f64>,
        gravity: [f64; 3],
        wind: Option<&Bound<'_, PyAny>>,
        thickness: f64,
        colliders: Option<&Bound<'_, PyAny>>,
        self_collision: Option<&Bound<'_, PyAny>>,
        bending: Option<&Bound<'_, PyAny>>,
        handles: Option<&Bound<'_, PyAny>>,
        tearing: Option<&Bound<'_, PyAny>>,
        uvs: Option<&Bound<'_, PyAny>>,
        backend: &str,
        method: Option<&str>,
        accumulation: Option<&str>,
        threads: Option<usize>,
        allow_unstable: bool,
    ) -> PyResult<Self> {
        use toml::Value;
        let choice = solver_choice(backend, method, accumulation, threads)?;
        let positions = convert::vectors(vertices, "vertices")?;
        let triangles = convert::triangles(triangles)?;
        let uvs = uvs
            .map(|uvs| convert::uvs(uvs, positions.len()))
            .transpose()?
            .map(|uvs| TextureCoordinates::per_vertex(uvs, &triangles));
        let mesh = Mesh {
            positions,
            triangles,
            uvs,
            ..Mesh::default()
        };
        let warnings = mesh.validate("arrays").or_raise()?;
        let stiffness = convert::per_item(stiffness, mesh.edges().len(), "stiffness")?;
        let masses = mass_per_vertex
            .map(|m| convert::per_item(m, mesh.vertex_count(), "mass_per_vertex"))
            .transpose()?;

        // The scene file these keywords make. Arrays are set on the model after the build; the
        // scene's checks see a placeholder for them.
        let placeholder = |item: &PerItem| match item {
            PerItem::One(value) => *value,
            PerItem::Each(_) => 1.0,
        };
        let mut mass = toml::Table::new();
        for (key, value) in [
            ("total", mass_total),
            ("per_vertex", masses.as_ref().map(placeholder)),
            ("area_density", area_density),
        ] {
            if let Some(value) = value {
                mass.insert(key.into(), Value::Float(value));
            }
        }
        let table = toml::toml! {
            [mesh]
            generator = "file"
        };
        let mut table = table;
        let mut material = toml::Table::new();
        material.insert("mass".into(), Value::Table(mass));
        material.insert("stiffness".into(), Value::Float(placeholder(&stiffness)));
        material.insert(
            "stiffness_model".into(),
            Value::String(stiffness_model.into()),
        );
        material.insert("damping".into(), Value::Float(damping));
        table.insert("material".into(), Value::Table(material));
        let mut pin_section = toml::Table::new();
        let indices = pins.unwrap_or_default().into_iter();
        pin_section.insert(
            "vertices".into(),
            Value::Array(indices.map(|i| Value::Integer(i.into())).collect()),
        );
        pin_section.insert(
            "select".into(),
            Value::Array(
                select
                    .unwrap_or_default()
                    .into_iter()
                    .map(Value::String)
                    .collect(),
            ),
        );
        table.insert("pins".into(), Value::Table(pin_section));
        let mut simulation = toml::Table::new();
        if let Some(dt) = dt {
            simulation.insert("dt".into(), Value::Float(dt));
        }
        simulation.insert(
            "gravity".into(),
            Value::Array(gravity.into_iter().map(Value::Float).collect()),
        );
        table.insert("simulation".into(), Value::Table(simulation));
        let mut collision = toml::Table::new();
        collision.insert("thickness".into(), Value::Float(thickness));
        table.insert("collision".into(), Value::Table(collision));
        for (key, value) in [
            ("wind", wind),
            ("collider", colliders),
            ("self_collision", self_collision),
            ("bending", bending),
            ("handle", handles),
            ("tearing", tearing),
        ] {
            if let Some(value) = value {
                table.insert(key.into(), convert::to_toml(value, key)?);
            }
        }

        let name = Path::new("arrays");
        let file: SceneFile = Value::Table(table)
            .try_into()
            .map_err(|e: toml::de::Error| input(format!("arrays: {}", e.message())))?;
        let mut scene = file
            .build_with_mesh(mesh, warnings, name, true)
            .or_raise()?;
        if let PerItem::Each(values) = stiffness {
            // One per edge spring; bending springs, after them, keep their own.
            scene.model.stiffnesses[..values.len()].copy_from_slice(&values);
        }
        if let Some(PerItem::Each(values)) = masses {
            scene.model.masses = values;
        }
        scene
            .set_time_step(file.simulation.dt, name, allow_unstable)
            .or_raise()?;
        open(&scene, choice)
    }

    fn __repr__(&self) -> PyResult<String> {
        let description = self.with(|s| Ok(s.describe()))?;
        Ok(format!("<hooke.Simulation {}: {description}>", self.name))
    }

    /// The scene's name.
    #[getter]
    pub(crate) fn name(&self) -> &str {
        &self.name
    }

    /// The solver, e.g. `"cpu gather (f32, 2 threads)"`.
    fn describe(&self) -> PyResult<String> {
        self.with(|s| Ok(s.describe()))
    }

    #[getter]
    fn vertex_count(&self) -> PyResult<usize> {
        self.with(|s| Ok(s.model().vertex_count()))
    }

    #[getter]
    fn spring_count(&self) -> PyResult<usize> {
        self.with(|s| Ok(s.model().spring_count()))
    }

    /// Of `spring_count`, the bending springs: the last ones in `springs()`.
    #[getter]
    fn bending_spring_count(&self) -> PyResult<usize> {
        self.with(|s| Ok(s.model().bending_springs))
    }

    /// The springs torn so far (indices into `springs()`), in order: an `(B,)` array.
    fn broken_springs<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, numpy::PyArray1<u32>>> {
        let broken = self.with(|s| s.broken_springs().or_raise())?;
        Ok(numpy::PyArray1::from_vec(py, broken))
    }

    #[getter]
    fn steps_taken(&self) -> PyResult<u64> {
        self.with(|s| Ok(s.steps_taken()))
    }

    /// Simulated time, s.
    #[getter]
    fn time(&self) -> PyResult<f64> {
        self.with(|s| Ok(s.time()))
    }

    #[getter]
    fn dt(&self) -> PyResult<f64> {
        self.with(|s| Ok(s.material().dt))
    }

    #[getter]
    fn damping(&self) -> PyResult<f64> {
        self.with(|s| Ok(s.material().damping))
    }

    #[getter]
    fn stiffness_scale(&self) -> PyResult<f64> {
        self.with(|s| Ok(s.material().stiffness_scale))
    }

    #[getter]
    fn gravity(&self) -> PyResult<[f64; 3]> {
        self.with(|s| Ok(s.material().gravity.to_array()))
    }

    /// Advances `steps` time steps. The GIL is released meanwhile: other Python threads run.
    fn step(&self, py: Python<'_>, steps: u64) -> PyResult<()> {
        py.detach(|| {
            let mut left = steps;
            self.with(|s| {
                while left > 0 {
                    let batch = left.min(u64::from(u32::MAX));
                    s.step(batch as u32).or_raise()?;
                    left -= batch;
                }
                Ok(())
            })
        })
    }

    /// Raises SimulationError if the GPU solver has met a non-finite position (the CPU solvers
    /// check every step).
    fn check(&self) -> PyResult<()> {
        self.with(|s| match s.gpu_solver_mut() {
            Some(solver) => solver.check().or_raise(),
            None => Ok(()),
        })
    }

    /// Current positions, float32 `(N, 3)`, m.
    fn positions<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyArray2<f32>>> {
        let state = self.with(|s| s.state().or_raise())?;
        Ok(convert::positions_f32(py, &state.positions))
    }

    /// Positions one step ago, float32 `(N, 3)`, m (Verlet's velocity is their difference / dt).
    fn previous_positions<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyArray2<f32>>> {
        let state = self.with(|s| s.state().or_raise())?;
        Ok(convert::positions_f32(py, &state.previous_positions))
    }

    /// Sets the positions, `(N, 3)`; `previous` defaults to the same (at rest).
    #[pyo3(signature = (positions, previous = None))]
    fn set_positions(
        &self,
        positions: &Bound<'_, PyAny>,
        previous: Option<&Bound<'_, PyAny>>,
    ) -> PyResult<()> {
        let positions = convert::vectors(positions, "positions")?;
        let previous_positions = match previous {
            Some(p) => convert::vectors(p, "previous")?,
            None => positions.clone(),
        };
        self.with(|s| {
            let n = s.model().vertex_count();
            if positions.len() != n || previous_positions.len() != n {
                return Err(input(format!(
                    "positions must have {n} rows (one per vertex), found {} and {}",
                    positions.len(),
                    previous_positions.len()
                )));
            }
            s.set_state(&State {
                positions,
                previous_positions,
            });
            Ok(())
        })
    }

    /// The state, balls and step counter, to `restore` later.
    fn snapshot(&self) -> PyResult<Snapshot> {
        Ok(Snapshot {
            inner: self.with(|s| s.snapshot().or_raise())?,
        })
    }

    /// Continues from a snapshot of this simulation.
    fn restore(&self, snapshot: &Snapshot) -> PyResult<()> {
        self.with(|s| {
            if snapshot.inner.state.positions.len() != s.model().vertex_count() {
                return Err(input("the snapshot is of another mesh"));
            }
            s.restore(&snapshot.inner).or_raise()
        })
    }

    /// Writes the state as `hooke run` writes `final-state.ply` (with its `.toml` sidecar), so
    /// that `hooke run --resume` or `load_state` continues it.
    fn save_state(&self, path: PathBuf) -> PyResult<()> {
        self.with(|s| {
            let snapshot = s.snapshot().or_raise()?;
            hooke::state_file::save_state(&path, &snapshot, s.model(), s.material().dt).or_raise()
        })
    }

    /// Continues from a state saved by `save_state` or `hooke run`.
    fn load_state(&self, path: PathBuf) -> PyResult<()> {
        self.with(|s| {
            let snapshot =
                hooke::state_file::load_state(&path, s.model(), s.material().dt).or_raise()?;
            s.restore(&snapshot).or_raise()
        })
    }

    /// Writes the current positions as a binary PLY frame, as `hooke run` writes its frames.
    fn write_frame(&self, path: PathBuf) -> PyResult<()> {
        self.with(|s| {
            let state = s.state().or_raise()?;
            let triangles = &s.model().triangles;
            hooke_core::mesh::write_ply_frame(&path, &state.positions, triangles, self.uvs())
                .map_err(|e| input(format!("{}: {e}", path.display())))
        })
    }

    /// Pulls vertices toward targets: a list of `(vertices, target, stiffness)`, vertices an
    /// index or a list of them, stiffness in N/m per vertex. Replaces the previous drags.
    fn set_drags(&self, drags: Vec<(Bound<'_, PyAny>, [f64; 3], f64)>) -> PyResult<()> {
        let drags = drags
            .into_iter()
            .map(|(vertices, target, stiffness)| {
                let vertices = match vertices.extract::<u32>() {
                    Ok(one) => vec![one],
                    Err(_) => vertices.extract::<Vec<u32>>().map_err(|_| {
                        input("a drag's vertices must be an index or a list of indices")
                    })?,
                };
                if !(stiffness >= 0.0 && stiffness.is_finite()) {
                    return Err(input(format!(
                        "a drag's stiffness must be zero or positive, found {stiffness}"
                    )));
                }
                Ok(Drag {
                    vertices,
                    target: vector(target, "a drag's target")?,
                    stiffness,
                })
            })
            .collect::<PyResult<Vec<_>>>()?;
        self.update_control(|control| control.drags = drags)
    }

    /// Constant forces on vertices: a list of `(vertex, force)`, N. Replaces the previous ones.
    fn set_point_forces(&self, forces: Vec<(u32, [f64; 3])>) -> PyResult<()> {
        let forces: Vec<PointForce> = indexed_forces(forces, "a point force")?
            .into_iter()
            .map(|(vertex, force)| PointForce { vertex, force })
            .collect();
        self.update_control(|control| control.point_forces = forces)
    }

    /// Wind of air `velocity` (m/s) with drag `coefficient` (N s/m^3); `None` stops it.
    #[pyo3(signature = (velocity, coefficient = 0.5))]
    fn set_wind(&self, velocity: Option<[f64; 3]>, coefficient: f64) -> PyResult<()> {
        let wind = match velocity {
            None => None,
            Some(v) => {
                if !(coefficient >= 0.0 && coefficient.is_finite()) {
                    return Err(input(format!(
                        "the wind coefficient must be zero or positive, found {coefficient}"
                    )));
                }
                Some(Wind {
                    velocity: vector(v, "the wind velocity")?,
                    coefficient,
                })
            }
        };
        self.update_control(|control| control.wind = wind)
    }

    /// Forces on dynamic balls: a list of `(collider index, force)`, N, added to each ball's own.
    fn set_ball_forces(&self, forces: Vec<(usize, [f64; 3])>) -> PyResult<()> {
        let pushes: Vec<BallPush> = indexed_forces(forces, "a ball force")?
            .into_iter()
            .map(|(collider, force)| BallPush { collider, force })
            .collect();
        self.update_control(|control| control.ball_pushes = pushes)
    }

    /// Changes dt (s), damping (kg/s), the stiffness scale or gravity (m/s^2) in place. A dt
    /// above the stability bound is refused unless `allow_unstable`.
    #[pyo3(signature = (*, dt = None, damping = None, stiffness_scale = None, gravity = None, allow_unstable = false))]
    fn set_material(
        &self,
        dt: Option<f64>,
        damping: Option<f64>,
        stiffness_scale: Option<f64>,
        gravity: Option<[f64; 3]>,
        allow_unstable: bool,
    ) -> PyResult<()> {
        self.with(|s| {
            let mut material = *s.material();
            for (name, value, zero_allowed) in [
                ("dt", dt, false),
                ("damping", damping, true),
                ("stiffness_scale", stiffness_scale, false),
            ] {
                if let Some(value) = value {
                    let ok = value.is_finite() && (value > 0.0 || (zero_allowed && value == 0.0));
                    if !ok {
                        return Err(input(format!("{name} must be positive, found {value}")));
                    }
                }
            }
            material.dt = dt.unwrap_or(material.dt);
            material.damping = damping.unwrap_or(material.damping);
            material.stiffness_scale = stiffness_scale.unwrap_or(material.stiffness_scale);
            if let Some(g) = gravity {
                material.gravity = vector(g, "gravity")?;
            }
            let limit = s.stability_limit_under(&material);
            if material.dt > limit.max_dt && !allow_unstable {
                return Err(input(format!(
                    "dt {:e} s is above the stability bound {:e} s of this stiffness and \
                     damping (pass allow_unstable=True to run it anyway)",
                    material.dt, limit.max_dt
                )));
            }
            s.set_material(material).or_raise()
        })
    }

    /// Turns approximate self-collision on (a dict as the scene's `[self_collision]`) or off
    /// (`None`).
    fn set_self_collision(&self, settings: Option<&Bound<'_, PyDict>>) -> PyResult<()> {
        let config = match settings {
            None => None,
            Some(settings) => {
                let section: hooke_core::scene::SelfCollisionSection =
                    convert::to_toml(settings, "self_collision")?
                        .try_into()
                        .map_err(|e: toml::de::Error| {
                            input(format!("self_collision: {}", e.message()))
                        })?;
                let invalid =
                    |field: &str, message: String| hooke_core::scene::SceneError::Invalid {
                        path: "set_self_collision".into(),
                        field: field.to_owned(),
                        message,
                    };
                section.params(&invalid).or_raise()?
            }
        };
        self.with(|s| s.set_self_collision(config).or_raise())
    }

    /// Pins `vertex` where it is, or at `at` (m, at rest there), until `unpin`: a gripper or a
    /// hanger put on while running. The solver is rebuilt, carrying the run on.
    #[pyo3(signature = (vertex, at = None))]
    fn pin(&self, vertex: u32, at: Option<[f64; 3]>) -> PyResult<()> {
        self.with(|s| s.pin(vertex, at.map(DVec3::from_array)).or_raise())
    }

    /// Lets a pinned vertex (a scene pin too) move again, from rest where it is.
    fn unpin(&self, vertex: u32) -> PyResult<()> {
        self.with(|s| s.unpin(vertex).or_raise())
    }

    /// Kinetic, elastic, gravitational and total energy, J.
    fn energy<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyDict>> {
        let energy = self.with(|s| {
            let state = s.state().or_raise()?;
            Ok(hooke_core::diagnostics::energy(
                &*s.torn_model().or_raise()?,
                &state,
                s.material(),
            ))
        })?;
        let dict = PyDict::new(py);
        dict.set_item("kinetic", energy.kinetic)?;
        dict.set_item("elastic", energy.elastic)?;
        dict.set_item("gravitational", energy.gravitational)?;
        dict.set_item("total", energy.total())?;
        Ok(dict)
    }

    /// The largest strain `|l| / l0 - 1` of any spring still whole, and that spring's index.
    fn max_strain(&self) -> PyResult<(f64, usize)> {
        self.with(|s| {
            let state = s.state().or_raise()?;
            Ok(hooke_core::diagnostics::max_strain(
                &*s.torn_model().or_raise()?,
                &state.positions,
            ))
        })
    }

    /// The force each pin exerts to hold its vertex: (vertex indices `(P,)`, forces `(P, 3)` N).
    #[allow(clippy::type_complexity)] // a (indices, forces) pair of arrays
    fn pin_reactions<'py>(
        &self,
        py: Python<'py>,
    ) -> PyResult<(Bound<'py, numpy::PyArray1<u32>>, Bound<'py, PyArray2<f64>>)> {
        let reactions = self.with(|s| {
            let state = s.state().or_raise()?;
            Ok(hooke_core::diagnostics::pin_reactions(
                &*s.torn_model().or_raise()?,
                &state.positions,
                s.material(),
            ))
        })?;
        let vertices: Vec<u32> = reactions.iter().map(|(i, _)| *i as u32).collect();
        let forces: Vec<[f64; 3]> = reactions.iter().map(|(_, f)| f.to_array()).collect();
        Ok((
            numpy::PyArray1::from_vec(py, vertices),
            convert::rows(py, &forces),
        ))
    }

    /// The colliders where they are now, as dicts (kind, shape, velocity, and for a dynamic
    /// ball its mass and spin).
    fn colliders<'py>(&self, py: Python<'py>) -> PyResult<Vec<Bound<'py, PyDict>>> {
        let colliders = self.with(|s| s.colliders().or_raise())?;
        colliders
            .iter()
            .map(|c| {
                let dict = PyDict::new(py);
                match c.shape {
                    hooke_core::collide::Shape::Sphere { center, radius } => {
                        dict.set_item("kind", "sphere")?;
                        dict.set_item("center", center.to_array())?;
                        dict.set_item("radius", radius)?;
                    }
                    hooke_core::collide::Shape::Plane { point, normal } => {
                        dict.set_item("kind", "plane")?;
                        dict.set_item("point", point.to_array())?;
                        dict.set_item("normal", normal.to_array())?;
                    }
                    hooke_core::collide::Shape::Capsule { start, end, radius } => {
                        dict.set_item("kind", "capsule")?;
                        dict.set_item("start", start.to_array())?;
                        dict.set_item("end", end.to_array())?;
                        dict.set_item("radius", radius)?;
                    }
                }
                dict.set_item("friction", c.friction)?;
                dict.set_item("velocity", c.velocity.to_array())?;
                dict.set_item("dynamic", c.dynamics.is_some())?;
                if let Some(dynamics) = &c.dynamics {
                    dict.set_item("mass", dynamics.mass)?;
                    dict.set_item("spin", c.spin.to_array())?;
                }
                Ok(dict)
            })
            .collect()
    }

    /// The largest stable dt under the current damping and stiffness scale, s, and the vertex
    /// that sets it.
    fn stable_dt(&self) -> PyResult<(f64, Option<usize>)> {
        self.with(|s| {
            let limit = s.stability_limit();
            Ok((limit.max_dt, limit.limiting_vertex))
        })
    }

    /// Bytes the solver holds, by role (the reference reports none).
    fn memory<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyDict>> {
        let report = self.with(|s| Ok(s.memory()))?;
        let dict = PyDict::new(py);
        match report {
            hooke::MemoryReport::Reference => {}
            hooke::MemoryReport::Cpu(m) => {
                dict.set_item("positions", m.positions)?;
                dict.set_item("topology", m.topology)?;
                dict.set_item("per_step", m.per_step)?;
                dict.set_item("total", m.total())?;
            }
            hooke::MemoryReport::Gpu(m) => {
                dict.set_item("positions", m.positions)?;
                dict.set_item("topology", m.topology)?;
                dict.set_item("per_step", m.per_step)?;
                dict.set_item("control", m.control)?;
                dict.set_item("total", m.total())?;
            }
        }
        Ok(dict)
    }

    /// One step with each phase timed, in ms (`force_accumulation` only where the sums take
    /// passes of their own: CPU scatter, GPU blend, and GPU incidence where its rows do not
    /// pad cheaply, as on irregular meshes), and how
    /// (`"timestamps"` on a GPU that has them, else `"wall-clock"`). `self_collision` holds
    /// its parts within `collision` where the solver times them (the CPU's), else None.
    fn step_timed<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyDict>> {
        let (times, source) = py.detach(|| self.with(|s| s.step_timed().or_raise()))?;
        timed_step_dict(py, &times, source)
    }

    /// `steps` steps each timed as `step_timed` times one, a dict a step. A GPU records up to
    /// 10 of them back to back in one submission, as plain steps run, so it does not idle
    /// between them.
    fn steps_timed<'py>(&self, py: Python<'py>, steps: u32) -> PyResult<Vec<Bound<'py, PyDict>>> {
        let (times, source) = py.detach(|| self.with(|s| s.steps_timed(steps).or_raise()))?;
        times
            .iter()
            .map(|step| timed_step_dict(py, step, source))
            .collect()
    }

    /// Triangles, `(T, 3)` uint32.
    fn triangles<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyArray2<u32>>> {
        self.with(|s| Ok(convert::rows(py, &s.model().triangles)))
    }

    /// Springs as vertex pairs, `(S, 2)` uint32, in the order of per-spring arrays.
    fn springs<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyArray2<u32>>> {
        self.with(|s| Ok(convert::rows(py, &s.model().spring_ends)))
    }

    /// Pinned vertex indices.
    fn pins(&self) -> PyResult<Vec<u32>> {
        self.with(|s| {
            Ok(s.model()
                .pinned
                .iter()
                .enumerate()
                .filter(|(_, p)| **p)
                .map(|(i, _)| i as u32)
                .collect())
        })
    }

    /// Draws the cloth and colliders as `hooke render` does, `(height, width, 4)` uint8 RGBA.
    /// A CPU simulation opens the default GPU to draw with; the reference cannot be drawn.
    #[pyo3(signature = (width = 640, height = 360, *, strain = false, wireframe = false))]
    fn render<'py>(
        &self,
        py: Python<'py>,
        width: u32,
        height: u32,
        strain: bool,
        wireframe: bool,
    ) -> PyResult<Bound<'py, numpy::PyArray3<u8>>> {
        if !(1..=8192).contains(&width) || !(1..=8192).contains(&height) {
            return Err(input(format!(
                "width and height must be 1..=8192, found {width}x{height}"
            )));
        }
        let image = py.detach(|| {
            let mut guard = self.lock()?;
            let holder = guard.take().ok_or_else(|| HookeError::new_err("in use"))?;
            let mut run = match holder {
                Holder::Drawing(run) if run.size() == [width, height] => run,
                Holder::Drawing(run) => Box::new(
                    OffscreenRun::new(run.simulation, [width, height])
                        .map_err(crate::errors::IntoPyErr::into_py_err)?,
                ),
                Holder::Bare(mut simulation) => {
                    if simulation.gpu().is_none() {
                        match hooke_gpu::GpuContext::new() {
                            Ok(gpu) => simulation.draw_with(gpu),
                            Err(e) => {
                                *guard = Some(Holder::Bare(simulation));
                                return Err(crate::errors::IntoPyErr::into_py_err(e));
                            }
                        }
                    }
                    match OffscreenRun::new(*simulation, [width, height]) {
                        Ok(run) => Box::new(run),
                        Err(e) => return Err(crate::errors::IntoPyErr::into_py_err(e)),
                    }
                }
            };
            run.options.color_by_strain = strain;
            run.options.wireframe = wireframe;
            let image = run.frame(0);
            *guard = Some(Holder::Drawing(run));
            image.or_raise()
        })?;
        let [w, h] = image.size;
        numpy::ndarray::Array3::from_shape_vec((h as usize, w as usize, 4), image.rgba)
            .map(|a| numpy::IntoPyArray::into_pyarray(a, py))
            .map_err(|e| HookeError::new_err(e.to_string()))
    }

    /// Draws as `render` does and saves a PNG (through a temporary file and a rename).
    #[pyo3(signature = (path, width = 640, height = 360, *, strain = false, wireframe = false))]
    fn save_png(
        &self,
        py: Python<'_>,
        path: PathBuf,
        width: u32,
        height: u32,
        strain: bool,
        wireframe: bool,
    ) -> PyResult<()> {
        let rgba = self.render(py, width, height, strain, wireframe)?;
        let image = hooke_gpu::render::Image {
            size: [width, height],
            rgba: rgba.to_vec()?,
        };
        image.save_png(&path).or_raise()
    }
}

/// `(index, force)` pairs with every force checked finite; `what` names them in errors.
fn indexed_forces<I>(forces: Vec<(I, [f64; 3])>, what: &str) -> PyResult<Vec<(I, DVec3)>> {
    forces
        .into_iter()
        .map(|(index, force)| Ok((index, vector(force, what)?)))
        .collect()
}

impl Simulation {
    fn lock(&self) -> PyResult<MutexGuard<'_, Option<Holder>>> {
        self.holder
            .lock()
            .map_err(|_| HookeError::new_err("the simulation was left broken by an earlier panic"))
    }

    /// Runs `f` on the simulation, holding its lock.
    pub(crate) fn uvs(&self) -> Option<&TextureCoordinates> {
        self.uvs.as_ref()
    }

    pub(crate) fn with<R>(
        &self,
        f: impl FnOnce(&mut hooke::Simulation) -> PyResult<R>,
    ) -> PyResult<R> {
        let mut guard = self.lock()?;
        let holder = guard
            .as_mut()
            .ok_or_else(|| HookeError::new_err("the simulation is in use"))?;
        f(holder.simulation())
    }

    /// Changes the control through `f`, checks it against the model and sends it.
    fn update_control(&self, f: impl FnOnce(&mut Control)) -> PyResult<()> {
        self.with(|s| {
            let mut control = s.control().clone();
            f(&mut control);
            control.check(s.model()).map_err(input)?;
            s.set_control(control).or_raise()
        })
    }
}

/// A timed step as `Simulation.step_timed` returns it: each phase in ms, and how it was timed.
fn timed_step_dict<'py>(
    py: Python<'py>,
    times: &hooke_core::PhaseTimes,
    source: hooke_core::TimingSource,
) -> PyResult<Bound<'py, PyDict>> {
    let ms = |d: std::time::Duration| d.as_secs_f64() * 1e3;
    let dict = PyDict::new(py);
    dict.set_item("external", ms(times.external))?;
    dict.set_item("force_calculation", ms(times.force_calculation))?;
    dict.set_item("force_accumulation", times.force_accumulation.map(ms))?;
    dict.set_item("integration", ms(times.integration))?;
    dict.set_item("collision", ms(times.collision))?;
    let parts = match times.self_collision {
        Some(parts) => {
            let dict = PyDict::new(py);
            dict.set_item("measuring", ms(parts.measuring))?;
            dict.set_item("pairs", ms(parts.pairs))?;
            dict.set_item("covering", ms(parts.covering))?;
            dict.set_item("sorting", ms(parts.sorting))?;
            dict.set_item("window_tests", ms(parts.window_tests))?;
            dict.set_item("moving", ms(parts.moving))?;
            dict.set_item("total", ms(parts.total()))?;
            Some(dict)
        }
        None => None,
    };
    dict.set_item("self_collision", parts)?;
    dict.set_item("total", ms(times.total()))?;
    let source = match source {
        hooke_core::TimingSource::Timestamps => "timestamps",
        hooke_core::TimingSource::WallClock => "wall-clock",
    };
    dict.set_item("source", source)?;
    Ok(dict)
}
