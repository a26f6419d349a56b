//! Scene files: a TOML description of a mesh, its material, pins, forces and run settings.
//!
//! Parsing rejects unknown keys and wrong types with the file, line and key (from `toml`);
//! [`SceneFile::build`] then checks ranges and names the offending field. See `scenes/README.md`
//! for the format with an example of every key.

use std::path::{Path, PathBuf};

use glam::DVec3;
use serde::{Deserialize, Deserializer, Serialize};

use crate::collide::{Collider, Dynamics, KeyframePath, MAX_KEYFRAMES, Shape};
use crate::mesh::{self, GridPlane, Mesh, MeshWarning};
use crate::selfcollide::{self, SelfCollision};
use crate::stability::{AUTO_DT_SAFETY, stability_limit};
use crate::{Drag, MassModel, Model, ModelOptions, PointForce, SimParams, StiffnessModel, Wind};

/// A whole scene file.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct SceneFile {
    /// Shown in summaries; defaults to the file stem.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub name: Option<String>,
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub description: Option<String>,
    pub mesh: MeshSection,
    pub material: MaterialSection,
    #[serde(default)]
    pub pins: PinSection,
    #[serde(default)]
    pub simulation: SimulationSection,
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub wind: Option<WindSection>,
    #[serde(default, rename = "force", skip_serializing_if = "Vec::is_empty")]
    pub forces: Vec<ForceSection>,
    #[serde(default, rename = "drag", skip_serializing_if = "Vec::is_empty")]
    pub drags: Vec<DragSection>,
    #[serde(default, rename = "collider", skip_serializing_if = "Vec::is_empty")]
    pub colliders: Vec<ColliderSection>,
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub collision: Option<CollisionSection>,
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub self_collision: Option<SelfCollisionSection>,
}

/// Approximate self-collision by binning (see `hooke_core::selfcollide`).
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct SelfCollisionSection {
    #[serde(default = "yes")]
    pub enabled: bool,
    /// Unjoined vertices are kept this far apart, m.
    pub distance: f64,
    /// Grid cell edge, m; defaults to twice `distance` (see `hooke selfcollision-study`).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub cell_size: Option<f64>,
    /// Staggered grids, 1..=16.
    #[serde(default = "default_grids")]
    pub grids: u32,
    /// Vertices tested on each side in sorted order, 1..=64.
    #[serde(default = "default_window")]
    pub window: u32,
}

fn yes() -> bool {
    true
}
fn default_grids() -> u32 {
    4
}
fn default_window() -> u32 {
    4
}

#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum ColliderKind {
    Sphere,
    Plane,
    Capsule,
}

/// A sphere (`center`, `radius`), a plane (`point`, `normal`; solid behind the normal) or a
/// capsule (`start`, `end`, `radius`).
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct ColliderSection {
    pub kind: ColliderKind,
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub center: Option<[f64; 3]>,
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub radius: Option<f64>,
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub point: Option<[f64; 3]>,
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub normal: Option<[f64; 3]>,
    /// A capsule's axis runs from `start` to `end`.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub start: Option<[f64; 3]>,
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub end: Option<[f64; 3]>,
    /// Share of tangential motion removed per contact step, 0..1.
    #[serde(default)]
    pub friction: f64,
    /// Scripted velocity (m/s): a kinematic collider moves on this straight path. A dynamic
    /// ball starts with it.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub velocity: Option<[f64; 3]>,
    /// kg: makes a sphere a dynamic ball, moved by gravity, `force` and the cloth.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub mass: Option<f64>,
    /// A constant force on a dynamic ball, N.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub force: Option<[f64; 3]>,
    /// A dynamic ball's bounce off planes and spheres, 0..=1 (default 0.3).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub restitution: Option<f64>,
    /// A scripted path: keyframes `[t, x, y, z]` of the centre or point, 2 to 8, times
    /// increasing; straight lines between them. `center`/`point` default to the first.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub path: Option<Vec<[f64; 4]>>,
    /// Start the path over after its last keyframe.
    #[serde(default)]
    pub repeat: bool,
}

#[derive(Clone, Debug, Default, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct CollisionSection {
    /// Distance at which the cloth is held from collider surfaces, m.
    #[serde(default)]
    pub thickness: f64,
}

/// Where the mesh comes from.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum MeshGenerator {
    Grid,
    Irregular,
    File,
}

#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct MeshSection {
    pub generator: MeshGenerator,
    /// grid: vertices along each side `[columns, rows]`.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub resolution: Option<[u32; 2]>,
    /// irregular: number of vertices.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub vertices: Option<u32>,
    /// irregular: random seed.
    #[serde(default)]
    pub seed: u64,
    /// grid, irregular: side lengths in metres.
    #[serde(default = "unit_size")]
    pub size: [f64; 2],
    #[serde(default)]
    pub plane: GridPlane,
    #[serde(default)]
    pub center: [f64; 3],
    /// file: path of an .obj or .ply, relative to the scene file.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub path: Option<PathBuf>,
}

fn unit_size() -> [f64; 2] {
    [1.0, 1.0]
}

impl MeshSection {
    /// A grid of `columns x rows` vertices over the unit square in the x-z plane.
    pub fn unit_grid(columns: u32, rows: u32) -> Self {
        Self {
            generator: MeshGenerator::Grid,
            resolution: Some([columns, rows]),
            vertices: None,
            seed: 0,
            size: unit_size(),
            plane: GridPlane::Xz,
            center: [0.0; 3],
            path: None,
        }
    }

    /// An irregular mesh of about `vertices` vertices over the unit square in the x-z plane.
    pub fn unit_irregular(vertices: u32, seed: u64) -> Self {
        Self {
            generator: MeshGenerator::Irregular,
            resolution: None,
            vertices: Some(vertices),
            seed,
            ..Self::unit_grid(2, 2)
        }
    }
}

#[derive(Clone, Debug, Default, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct MassSection {
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub total: Option<f64>,
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub per_vertex: Option<f64>,
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub area_density: Option<f64>,
}

#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "kebab-case")]
pub enum StiffnessKind {
    #[default]
    Uniform,
    InverseRestLength,
}

#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct MaterialSection {
    pub mass: MassSection,
    /// Spring stiffness `D`, N/m.
    pub stiffness: f64,
    #[serde(default)]
    pub stiffness_model: StiffnessKind,
    /// Damping constant `c`, kg/s.
    #[serde(default)]
    pub damping: f64,
    #[serde(default = "one")]
    pub rest_length_scale: f64,
}

fn one() -> f64 {
    1.0
}

/// Named groups of vertices to pin.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "kebab-case")]
pub enum PinSelector {
    /// The four vertices nearest the corners of the sheet's bounding rectangle.
    Corners,
    /// The two of those corners with the largest y.
    TopCorners,
    /// Every vertex whose y is the largest (within a millionth of the mesh size).
    TopEdge,
}

#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct PinBox {
    pub min: [f64; 3],
    pub max: [f64; 3],
}

#[derive(Clone, Debug, Default, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct PinSection {
    #[serde(default, skip_serializing_if = "Vec::is_empty")]
    pub select: Vec<PinSelector>,
    #[serde(default, skip_serializing_if = "Vec::is_empty")]
    pub vertices: Vec<u32>,
    #[serde(default, skip_serializing_if = "Vec::is_empty")]
    pub boxes: Vec<PinBox>,
}

/// `dt = "auto"` or a number of seconds.
#[derive(Clone, Copy, Debug, Default, PartialEq, Serialize)]
#[serde(untagged)]
pub enum TimeStep {
    #[default]
    #[serde(serialize_with = "serialize_auto")]
    Auto,
    Seconds(f64),
}

fn serialize_auto<S: serde::Serializer>(serializer: S) -> Result<S::Ok, S::Error> {
    serializer.serialize_str("auto")
}

impl<'de> Deserialize<'de> for TimeStep {
    fn deserialize<D: Deserializer<'de>>(deserializer: D) -> Result<Self, D::Error> {
        struct Visitor;
        impl serde::de::Visitor<'_> for Visitor {
            type Value = TimeStep;
            fn expecting(&self, f: &mut std::fmt::Formatter) -> std::fmt::Result {
                f.write_str("a time step in seconds or \"auto\"")
            }
            fn visit_f64<E: serde::de::Error>(self, v: f64) -> Result<TimeStep, E> {
                Ok(TimeStep::Seconds(v))
            }
            fn visit_i64<E: serde::de::Error>(self, v: i64) -> Result<TimeStep, E> {
                Ok(TimeStep::Seconds(v as f64))
            }
            fn visit_str<E: serde::de::Error>(self, v: &str) -> Result<TimeStep, E> {
                if v == "auto" {
                    Ok(TimeStep::Auto)
                } else {
                    Err(E::invalid_value(serde::de::Unexpected::Str(v), &self))
                }
            }
        }
        deserializer.deserialize_any(Visitor)
    }
}

#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct SimulationSection {
    #[serde(default)]
    pub dt: TimeStep,
    #[serde(default = "default_steps")]
    pub steps: u64,
    #[serde(default = "default_gravity")]
    pub gravity: [f64; 3],
    /// Steps between written frames.
    #[serde(default = "default_frame_every")]
    pub frame_every: u64,
}

fn default_steps() -> u64 {
    1000
}
fn default_gravity() -> [f64; 3] {
    [0.0, -9.81, 0.0]
}
fn default_frame_every() -> u64 {
    50
}

impl Default for SimulationSection {
    fn default() -> Self {
        Self {
            dt: TimeStep::Auto,
            steps: default_steps(),
            gravity: default_gravity(),
            frame_every: default_frame_every(),
        }
    }
}

#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct WindSection {
    /// m/s.
    pub velocity: [f64; 3],
    /// N s/m^3.
    pub coefficient: f64,
}

#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct ForceSection {
    pub vertices: Vec<u32>,
    /// N, applied to each listed vertex.
    pub force: [f64; 3],
}

#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct DragSection {
    pub vertices: Vec<u32>,
    pub target: [f64; 3],
    /// N/m.
    pub stiffness: f64,
}

/// Why a scene could not be loaded or built. Every message names the scene file.
#[derive(Debug, thiserror::Error)]
pub enum SceneError {
    #[error("{path}: {source}")]
    Io {
        path: String,
        source: std::io::Error,
    },
    #[error("{path}: {message}")]
    Parse { path: String, message: String },
    #[error("{path}: {field}: {message}")]
    Invalid {
        path: String,
        field: String,
        message: String,
    },
    #[error(transparent)]
    Mesh(#[from] mesh::MeshLoadError),
    #[error(
        "{path}: simulation.dt = {dt} s exceeds the stability limit {max_dt:.4e} s (set by vertex {vertex}); use a smaller dt, dt = \"auto\", or --allow-unstable"
    )]
    UnstableTimeStep {
        path: String,
        dt: f64,
        max_dt: f64,
        vertex: usize,
    },
}

/// A scene ready to simulate.
#[derive(Clone, Debug)]
pub struct Scene {
    pub name: String,
    pub mesh: Mesh,
    pub mesh_warnings: Vec<MeshWarning>,
    pub model: Model,
    pub params: SimParams,
    pub steps: u64,
    pub frame_every: u64,
    /// The stability bound on dt for this model, s.
    pub max_stable_dt: f64,
}

impl SceneFile {
    /// Reads and parses a scene file (no range checks yet; see [`SceneFile::build`]).
    pub fn load(path: &Path) -> Result<Self, SceneError> {
        let text = std::fs::read_to_string(path).map_err(|source| SceneError::Io {
            path: path.display().to_string(),
            source,
        })?;
        Self::parse(&text, &path.display().to_string())
    }

    pub fn parse(text: &str, path: &str) -> Result<Self, SceneError> {
        toml::from_str(text).map_err(|e| SceneError::Parse {
            path: path.to_owned(),
            message: e.to_string().trim_end().to_owned(),
        })
    }

    /// The scene as TOML text.
    pub fn to_toml(&self) -> String {
        toml::to_string(self).unwrap_or_else(|e| format!("# could not serialise scene: {e}"))
    }

    /// The comparability workload of `hooke bench` (issue 2): a unit square in the x-z plane,
    /// 4 corners pinned, m = 1/N per vertex, dt = 1e-3 s, D = 0.25 m/dt^2, c = 0.01 m/dt,
    /// gravity -9.81 m/s^2 along y. `vertex_count` must be the mesh's exact vertex count.
    pub fn benchmark(mesh: MeshSection, vertex_count: u32) -> Self {
        let dt = 1e-3;
        let mass = 1.0 / f64::from(vertex_count);
        Self {
            name: None,
            description: Some("hooke bench workload".to_owned()),
            mesh,
            material: MaterialSection {
                mass: MassSection {
                    total: Some(1.0),
                    ..Default::default()
                },
                stiffness: 0.25 * mass / (dt * dt),
                stiffness_model: StiffnessKind::Uniform,
                damping: 0.01 * mass / dt,
                rest_length_scale: 1.0,
            },
            pins: PinSection {
                select: vec![PinSelector::Corners],
                ..Default::default()
            },
            simulation: SimulationSection {
                dt: TimeStep::Seconds(dt),
                steps: 100,
                gravity: default_gravity(),
                frame_every: 100,
            },
            wind: None,
            forces: Vec::new(),
            drags: Vec::new(),
            colliders: Vec::new(),
            collision: None,
            self_collision: None,
        }
    }

    /// Checks every value, builds the mesh and model, and settles the time step.
    ///
    /// `path` locates mesh files and names the scene in errors. A dt above the stability bound is
    /// an error unless `allow_unstable`.
    pub fn build(&self, path: &Path, allow_unstable: bool) -> Result<Scene, SceneError> {
        let path_name = path.display().to_string();
        let invalid = |field: &str, message: String| SceneError::Invalid {
            path: path_name.clone(),
            field: field.to_owned(),
            message,
        };
        let (mesh, mesh_warnings) = self.build_mesh(path, &invalid)?;

        let material = &self.material;
        let mass = match (
            material.mass.total,
            material.mass.per_vertex,
            material.mass.area_density,
        ) {
            (Some(total), None, None) => MassModel::TotalUniform(total),
            (None, Some(m), None) => MassModel::PerVertex(m),
            (None, None, Some(rho)) => MassModel::AreaDensity(rho),
            _ => {
                return Err(invalid(
                    "material.mass",
                    "give exactly one of total, per_vertex or area_density".into(),
                ));
            }
        };
        for (field, value) in [
            ("material.mass.total", material.mass.total),
            ("material.mass.per_vertex", material.mass.per_vertex),
            ("material.mass.area_density", material.mass.area_density),
            ("material.stiffness", Some(material.stiffness)),
            (
                "material.rest_length_scale",
                Some(material.rest_length_scale),
            ),
        ] {
            if let Some(value) = value {
                require(value > 0.0 && value.is_finite(), || {
                    invalid(field, format!("must be a positive number, found {value}"))
                })?;
            }
        }
        require(
            material.damping >= 0.0 && material.damping.is_finite(),
            || {
                invalid(
                    "material.damping",
                    format!("must be zero or positive, found {}", material.damping),
                )
            },
        )?;
        let stiffness = match material.stiffness_model {
            StiffnessKind::Uniform => StiffnessModel::Uniform(material.stiffness),
            StiffnessKind::InverseRestLength => {
                StiffnessModel::InverseRestLength(material.stiffness)
            }
        };
        let pinned = self.resolve_pins(&mesh, &invalid)?;
        let options = ModelOptions {
            stiffness,
            mass,
            rest_length_scale: material.rest_length_scale,
            pinned,
        };
        let model =
            Model::from_mesh(&mesh, &options).map_err(|e| invalid("material", e.to_string()))?;

        let params = self.build_params(&mesh, &invalid)?;
        let limit = stability_limit(&model, params.damping);
        let dt = match self.simulation.dt {
            TimeStep::Auto => {
                require(limit.max_dt.is_finite(), || {
                    invalid(
                        "simulation.dt",
                        "\"auto\" needs springs or damping to bound the step; give dt in seconds"
                            .into(),
                    )
                })?;
                AUTO_DT_SAFETY * limit.max_dt
            }
            TimeStep::Seconds(dt) => {
                require(dt > 0.0 && dt.is_finite(), || {
                    invalid(
                        "simulation.dt",
                        format!("must be a positive number of seconds, found {dt}"),
                    )
                })?;
                if dt > limit.max_dt && !allow_unstable {
                    return Err(SceneError::UnstableTimeStep {
                        path: path_name,
                        dt,
                        max_dt: limit.max_dt,
                        vertex: limit.limiting_vertex.unwrap_or(0),
                    });
                }
                dt
            }
        };
        require(self.simulation.frame_every > 0, || {
            invalid("simulation.frame_every", "must be at least 1".into())
        })?;
        let name = self.name.clone().unwrap_or_else(|| {
            path.file_stem()
                .map(|s| s.to_string_lossy().into_owned())
                .unwrap_or_else(|| "scene".to_owned())
        });
        Ok(Scene {
            name,
            mesh,
            mesh_warnings,
            model,
            params: SimParams { dt, ..params },
            steps: self.simulation.steps,
            frame_every: self.simulation.frame_every,
            max_stable_dt: limit.max_dt,
        })
    }

    fn build_mesh(
        &self,
        path: &Path,
        invalid: &dyn Fn(&str, String) -> SceneError,
    ) -> Result<(Mesh, Vec<MeshWarning>), SceneError> {
        let section = &self.mesh;
        let center = DVec3::from_array(section.center);
        if section.generator != MeshGenerator::File {
            require(
                section.size.iter().all(|s| *s > 0.0 && s.is_finite()),
                || {
                    invalid(
                        "mesh.size",
                        format!("both sides must be positive, found {:?}", section.size),
                    )
                },
            )?;
        }
        let mesh = match section.generator {
            MeshGenerator::Grid => {
                let [columns, rows] = section.resolution.ok_or_else(|| {
                    invalid(
                        "mesh.resolution",
                        "a grid needs resolution = [columns, rows]".into(),
                    )
                })?;
                require(
                    (2..=8192).contains(&columns) && (2..=8192).contains(&rows),
                    || {
                        invalid(
                            "mesh.resolution",
                            format!(
                                "each side must be 2..=8192 vertices, found [{columns}, {rows}]"
                            ),
                        )
                    },
                )?;
                mesh::grid(columns, rows, section.size, section.plane, center)
            }
            MeshGenerator::Irregular => {
                let vertices = section.vertices.ok_or_else(|| {
                    invalid(
                        "mesh.vertices",
                        "an irregular mesh needs vertices = N".into(),
                    )
                })?;
                require((16..=50_000_000).contains(&vertices), || {
                    invalid(
                        "mesh.vertices",
                        format!("must be 16..=50000000, found {vertices}"),
                    )
                })?;
                mesh::irregular(vertices, section.size, section.seed, section.plane, center)
            }
            MeshGenerator::File => {
                let relative = section.path.as_ref().ok_or_else(|| {
                    invalid(
                        "mesh.path",
                        "generator = \"file\" needs path = \"mesh.obj\"".into(),
                    )
                })?;
                let file = path.parent().unwrap_or(Path::new("")).join(relative);
                let (mut mesh, warnings) = mesh::load_mesh(&file)?;
                for p in &mut mesh.positions {
                    *p += center;
                }
                return Ok((mesh, warnings));
            }
        };
        let warnings = mesh
            .validate(&format!("{} (generated mesh)", path.display()))
            .map_err(mesh::MeshLoadError::from)?;
        Ok((mesh, warnings))
    }

    fn resolve_pins(
        &self,
        mesh: &Mesh,
        invalid: &dyn Fn(&str, String) -> SceneError,
    ) -> Result<Vec<u32>, SceneError> {
        let count = mesh.vertex_count();
        let mut pinned = Vec::new();
        for &v in &self.pins.vertices {
            require((v as usize) < count, || {
                invalid(
                    "pins.vertices",
                    format!("vertex {v} does not exist (mesh has {count} vertices)"),
                )
            })?;
            pinned.push(v);
        }
        for selector in &self.pins.select {
            pinned.extend(select_vertices(mesh, *selector));
        }
        for (k, b) in self.pins.boxes.iter().enumerate() {
            let (lo, hi) = (DVec3::from_array(b.min), DVec3::from_array(b.max));
            let inside: Vec<u32> = (0..count as u32)
                .filter(|&i| {
                    let p = mesh.positions[i as usize];
                    p.cmpge(lo).all() && p.cmple(hi).all()
                })
                .collect();
            require(!inside.is_empty(), || {
                invalid(&format!("pins.boxes[{k}]"), "contains no vertex".into())
            })?;
            pinned.extend(inside);
        }
        pinned.sort_unstable();
        pinned.dedup();
        Ok(pinned)
    }

    fn build_params(
        &self,
        mesh: &Mesh,
        invalid: &dyn Fn(&str, String) -> SceneError,
    ) -> Result<SimParams, SceneError> {
        let count = mesh.vertex_count();
        let check_vertices =
            |field: &str, vertices: &[u32]| match vertices.iter().find(|v| **v as usize >= count) {
                Some(v) => Err(invalid(
                    field,
                    format!("vertex {v} does not exist (mesh has {count} vertices)"),
                )),
                None => Ok(()),
            };
        let finite = |field: &str, v: [f64; 3]| {
            require(v.iter().all(|x| x.is_finite()), || {
                invalid(field, format!("must be finite, found {v:?}"))
            })
        };
        finite("simulation.gravity", self.simulation.gravity)?;
        let wind = match &self.wind {
            Some(w) => {
                finite("wind.velocity", w.velocity)?;
                require(w.coefficient >= 0.0 && w.coefficient.is_finite(), || {
                    invalid(
                        "wind.coefficient",
                        format!("must be zero or positive, found {}", w.coefficient),
                    )
                })?;
                Some(Wind {
                    velocity: DVec3::from_array(w.velocity),
                    coefficient: w.coefficient,
                })
            }
            None => None,
        };
        let mut point_forces = Vec::new();
        for (k, f) in self.forces.iter().enumerate() {
            check_vertices(&format!("force[{k}].vertices"), &f.vertices)?;
            finite(&format!("force[{k}].force"), f.force)?;
            point_forces.extend(f.vertices.iter().map(|&vertex| PointForce {
                vertex,
                force: DVec3::from_array(f.force),
            }));
        }
        let mut drags = Vec::new();
        for (k, d) in self.drags.iter().enumerate() {
            check_vertices(&format!("drag[{k}].vertices"), &d.vertices)?;
            finite(&format!("drag[{k}].target"), d.target)?;
            require(d.stiffness >= 0.0 && d.stiffness.is_finite(), || {
                invalid(
                    &format!("drag[{k}].stiffness"),
                    format!("must be zero or positive, found {}", d.stiffness),
                )
            })?;
            drags.push(Drag {
                vertices: d.vertices.clone(),
                target: DVec3::from_array(d.target),
                stiffness: d.stiffness,
            });
        }
        let mut colliders = Vec::new();
        for (k, c) in self.colliders.iter().enumerate() {
            let field = |name: &str| format!("collider[{k}].{name}");
            let need = |name: &str, value: Option<[f64; 3]>| {
                let value = value.ok_or_else(|| {
                    invalid(
                        &field(name),
                        format!("a {:?} collider needs {name}", c.kind),
                    )
                })?;
                finite(&field(name), value)?;
                Ok::<DVec3, SceneError>(DVec3::from_array(value))
            };
            require((0.0..=1.0).contains(&c.friction), || {
                invalid(
                    &field("friction"),
                    format!("must be 0..=1, found {}", c.friction),
                )
            })?;
            // A scripted path starts where its first keyframe is.
            let start = c
                .path
                .as_ref()
                .and_then(|keys| keys.first())
                .map(|[_, x, y, z]| [*x, *y, *z]);
            let radius = || {
                let radius = c.radius.unwrap_or(f64::NAN);
                require(radius > 0.0 && radius.is_finite(), || {
                    invalid(
                        &field("radius"),
                        format!("must be a positive number, found {radius}"),
                    )
                })?;
                Ok::<f64, SceneError>(radius)
            };
            let shape = match c.kind {
                ColliderKind::Sphere => Shape::Sphere {
                    center: need("center", c.center.or(start))?,
                    radius: radius()?,
                },
                ColliderKind::Capsule => Shape::Capsule {
                    start: need("start", c.start.or(start))?,
                    end: need("end", c.end)?,
                    radius: radius()?,
                },
                ColliderKind::Plane => {
                    let normal = need("normal", c.normal)?;
                    let normal = normal
                        .try_normalize()
                        .ok_or_else(|| invalid(&field("normal"), "must not be zero".into()))?;
                    Shape::Plane {
                        point: need("point", c.point.or(start))?,
                        normal,
                    }
                }
            };
            let path = match &c.path {
                None => None,
                Some(keys) => {
                    for (name, set) in [
                        ("velocity", c.velocity.is_some()),
                        ("mass", c.mass.is_some()),
                    ] {
                        require(!set, || {
                            invalid(
                                &field(name),
                                "a collider with a path cannot have one".into(),
                            )
                        })?;
                    }
                    require(keys.iter().flatten().all(|x| x.is_finite()), || {
                        invalid(&field("path"), "keyframes must be finite".into())
                    })?;
                    let keys: Vec<(f64, DVec3)> = keys
                        .iter()
                        .map(|[t, x, y, z]| (*t, DVec3::new(*x, *y, *z)))
                        .collect();
                    Some(KeyframePath::new(&keys, c.repeat).ok_or_else(|| {
                        invalid(
                            &field("path"),
                            format!(
                                "needs 2 to {MAX_KEYFRAMES} keyframes [t, x, y, z] with increasing t, found {}",
                                keys.len()
                            ),
                        )
                    })?)
                }
            };
            let velocity = match c.velocity {
                Some(v) => {
                    finite(&field("velocity"), v)?;
                    DVec3::from_array(v)
                }
                None => DVec3::ZERO,
            };
            let dynamics = match (c.mass, c.kind) {
                (None, _) => {
                    for (name, set) in [
                        ("force", c.force.is_some()),
                        ("restitution", c.restitution.is_some()),
                    ] {
                        require(!set, || {
                            invalid(&field(name), "applies only to a ball with a mass".into())
                        })?;
                    }
                    None
                }
                (Some(_), ColliderKind::Plane | ColliderKind::Capsule) => {
                    return Err(invalid(
                        &field("mass"),
                        "only spheres can be dynamic".into(),
                    ));
                }
                (Some(mass), ColliderKind::Sphere) => {
                    require(mass > 0.0 && mass.is_finite(), || {
                        invalid(
                            &field("mass"),
                            format!("must be a positive number, found {mass}"),
                        )
                    })?;
                    let restitution = c.restitution.unwrap_or(0.3);
                    require((0.0..=1.0).contains(&restitution), || {
                        invalid(
                            &field("restitution"),
                            format!("must be 0..=1, found {restitution}"),
                        )
                    })?;
                    let force = c.force.unwrap_or([0.0; 3]);
                    finite(&field("force"), force)?;
                    Some(Dynamics {
                        mass,
                        force: DVec3::from_array(force),
                        restitution,
                    })
                }
            };
            colliders.push(Collider {
                shape,
                friction: c.friction,
                velocity,
                dynamics,
                spin: DVec3::ZERO,
                path,
            });
        }
        let collision_thickness = self.collision.as_ref().map_or(0.0, |c| c.thickness);
        require(
            collision_thickness >= 0.0 && collision_thickness.is_finite(),
            || {
                invalid(
                    "collision.thickness",
                    format!("must be zero or positive, found {collision_thickness}"),
                )
            },
        )?;
        let self_collision = self.self_collision_params(invalid)?;
        Ok(SimParams {
            dt: 0.0,
            damping: self.material.damping,
            gravity: DVec3::from_array(self.simulation.gravity),
            wind,
            point_forces,
            drags,
            colliders,
            collision_thickness,
            self_collision,
        })
    }

    fn self_collision_params(
        &self,
        invalid: &dyn Fn(&str, String) -> SceneError,
    ) -> Result<Option<SelfCollision>, SceneError> {
        let Some(section) = self.self_collision.as_ref().filter(|s| s.enabled) else {
            return Ok(None);
        };
        let positive = |name: &str, value: f64| {
            require(value > 0.0 && value.is_finite(), || {
                invalid(
                    &format!("self_collision.{name}"),
                    format!("must be a positive number, found {value}"),
                )
            })
        };
        positive("distance", section.distance)?;
        let cell_size = section.cell_size.unwrap_or(2.0 * section.distance);
        positive("cell_size", cell_size)?;
        for (name, value, max) in [
            ("grids", section.grids, selfcollide::MAX_GRIDS),
            ("window", section.window, selfcollide::MAX_WINDOW),
        ] {
            require((1..=max).contains(&value), || {
                invalid(
                    &format!("self_collision.{name}"),
                    format!("must be 1..={max}, found {value}"),
                )
            })?;
        }
        Ok(Some(SelfCollision {
            distance: section.distance,
            cell_size,
            grids: section.grids,
            window: section.window,
        }))
    }
}

fn require(condition: bool, error: impl FnOnce() -> SceneError) -> Result<(), SceneError> {
    if condition { Ok(()) } else { Err(error()) }
}

/// Vertices a named selector picks.
pub fn select_vertices(mesh: &Mesh, selector: PinSelector) -> Vec<u32> {
    let (lo, hi) = mesh.bounds();
    let extent = hi - lo;
    match selector {
        PinSelector::Corners | PinSelector::TopCorners => {
            // The sheet's plane is spanned by the two axes of largest extent.
            let mut axes = [0usize, 1, 2];
            axes.sort_by(|a, b| extent[*b].total_cmp(&extent[*a]));
            let (u, v) = (axes[0], axes[1]);
            let mut corners: Vec<u32> = [
                (lo[u], lo[v]),
                (hi[u], lo[v]),
                (lo[u], hi[v]),
                (hi[u], hi[v]),
            ]
            .iter()
            .map(|&(cu, cv)| nearest_vertex(mesh, |p| (p[u] - cu).powi(2) + (p[v] - cv).powi(2)))
            .collect();
            if selector == PinSelector::TopCorners {
                corners.sort_by(|a, b| {
                    mesh.positions[*b as usize]
                        .y
                        .total_cmp(&mesh.positions[*a as usize].y)
                });
                corners.truncate(2);
            }
            corners
        }
        PinSelector::TopEdge => {
            let tolerance = 1e-6 * extent.max_element();
            (0..mesh.vertex_count() as u32)
                .filter(|&i| mesh.positions[i as usize].y >= hi.y - tolerance)
                .collect()
        }
    }
}

fn nearest_vertex(mesh: &Mesh, distance: impl Fn(DVec3) -> f64) -> u32 {
    (0..mesh.vertex_count() as u32)
        .min_by(|a, b| {
            distance(mesh.positions[*a as usize]).total_cmp(&distance(mesh.positions[*b as usize]))
        })
        .unwrap_or(0)
}

#[cfg(test)]
mod tests {
    use super::*;

    const CLOTH: &str = r#"
[mesh]
generator = "grid"
resolution = [8, 8]

[material]
mass = { total = 0.5 }
stiffness = 200.0
damping = 0.01

[pins]
select = ["corners"]
"#;

    fn build(text: &str) -> Result<Scene, SceneError> {
        SceneFile::parse(text, "test.toml")?.build(Path::new("test.toml"), false)
    }

    #[test]
    fn minimal_scene_builds_with_auto_dt_below_the_bound() {
        let scene = build(CLOTH).expect("builds");
        assert_eq!(scene.model.pinned.iter().filter(|p| **p).count(), 4);
        assert!(scene.params.dt < scene.max_stable_dt);
        for corner in [0usize, 7, 56, 63] {
            assert!(scene.model.pinned[corner]);
        }
    }

    #[test]
    fn unknown_key_names_line_and_key() {
        let text = CLOTH.replace("damping = 0.01", "dampnig = 0.01");
        let message = build(&text).unwrap_err().to_string();
        assert!(
            message.contains("test.toml") && message.contains("line 9"),
            "{message}"
        );
        assert!(message.contains("dampnig"), "{message}");
    }

    #[test]
    fn negative_stiffness_names_the_field() {
        let text = CLOTH.replace("stiffness = 200.0", "stiffness = -1.0");
        assert_eq!(
            build(&text).unwrap_err().to_string(),
            "test.toml: material.stiffness: must be a positive number, found -1"
        );
    }

    #[test]
    fn unstable_dt_is_refused_unless_allowed() {
        let text = format!("{CLOTH}\n[simulation]\ndt = 0.5\n");
        let message = build(&text).unwrap_err().to_string();
        assert!(message.contains("exceeds the stability limit"), "{message}");
        let scene = SceneFile::parse(&text, "t")
            .expect("parses")
            .build(Path::new("t"), true)
            .expect("allowed");
        assert_eq!(scene.params.dt, 0.5);
    }

    #[test]
    fn dt_must_be_a_number_or_auto() {
        let text = format!("{CLOTH}\n[simulation]\ndt = \"fast\"\n");
        let message = build(&text).unwrap_err().to_string();
        assert!(message.contains("auto"), "{message}");
    }

    #[test]
    fn two_mass_kinds_are_ambiguous() {
        let text = CLOTH.replace("{ total = 0.5 }", "{ total = 0.5, per_vertex = 0.1 }");
        let message = build(&text).unwrap_err().to_string();
        assert!(message.contains("material.mass"), "{message}");
    }

    #[test]
    fn force_on_missing_vertex_names_the_entry() {
        let text = format!("{CLOTH}\n[[force]]\nvertices = [64]\nforce = [0, 1, 0]\n");
        assert_eq!(
            build(&text).unwrap_err().to_string(),
            "test.toml: force[0].vertices: vertex 64 does not exist (mesh has 64 vertices)"
        );
    }

    #[test]
    fn pins_combine_indices_selectors_and_boxes() {
        let text = CLOTH.replace(
            "select = [\"corners\"]",
            "select = [\"corners\"]\nvertices = [9]\nboxes = [{ min = [-0.6, -1, -0.6], max = [0.6, 1, -0.4] }]",
        );
        let scene = build(&text).expect("builds");
        let pinned: Vec<usize> = (0..64).filter(|&i| scene.model.pinned[i]).collect();
        // Corners 0, 7, 56, 63; vertex 9; the whole first row (z = -0.5) from the box.
        assert_eq!(pinned, vec![0, 1, 2, 3, 4, 5, 6, 7, 9, 56, 63]);
        let empty = CLOTH.replace(
            "select = [\"corners\"]",
            "boxes = [{ min = [5, 5, 5], max = [6, 6, 6] }]",
        );
        assert_eq!(
            build(&empty).unwrap_err().to_string(),
            "test.toml: pins.boxes[0]: contains no vertex"
        );
    }

    #[test]
    fn dynamic_balls_and_self_collision_are_read_and_checked() {
        let ball = "[[collider]]\nkind = \"sphere\"\ncenter = [0, 2, 0]\nradius = 0.2\nmass = 0.5\nforce = [1, 0, 0]\n";
        let text = format!("{CLOTH}\n{ball}\n[self_collision]\ndistance = 0.01\ngrids = 3\n");
        let scene = build(&text).expect("builds");
        let dynamics = scene.params.colliders[0].dynamics.expect("dynamic");
        assert_eq!((dynamics.mass, dynamics.restitution), (0.5, 0.3));
        assert_eq!(dynamics.force, DVec3::X);
        let config = scene.params.self_collision.expect("self-collision");
        assert_eq!((config.grids, config.window), (3, 4));
        assert_eq!(config.cell_size, 0.02);
        for (from, to, message) in [
            (
                "mass = 0.5",
                "mass = 0",
                "collider[0].mass: must be a positive number, found 0",
            ),
            (
                "force = [1, 0, 0]",
                "force = [1, 0, 0]\nrestitution = 2",
                "collider[0].restitution: must be 0..=1, found 2",
            ),
            (
                "grids = 3",
                "grids = 0",
                "self_collision.grids: must be 1..=16, found 0",
            ),
            (
                "distance = 0.01",
                "distance = -0.01",
                "self_collision.distance: must be a positive number, found -0.01",
            ),
        ] {
            let error = build(&text.replace(from, to)).unwrap_err().to_string();
            assert!(error.contains(message), "{error}");
        }
        let unpushed = text.replace("mass = 0.5\n", "");
        assert!(
            build(&unpushed)
                .unwrap_err()
                .to_string()
                .contains("collider[0].force: applies only to a ball with a mass")
        );
        let capsule = format!(
            "{CLOTH}\n[[collider]]\nkind = \"capsule\"\nstart = [0, 0, 0]\nend = [1, 0, 0]\nradius = 0.1\n"
        );
        assert!(matches!(
            build(&capsule).expect("builds").params.colliders[0].shape,
            Shape::Capsule { radius, .. } if radius == 0.1
        ));
        let error = build(&capsule.replace("end = [1, 0, 0]\n", ""))
            .unwrap_err()
            .to_string();
        assert!(error.contains("collider[0].end"), "{error}");
        let off = text.replace("grids = 3", "grids = 3\nenabled = false");
        assert!(build(&off).expect("builds").params.self_collision.is_none());
        // A keyframed path: the sphere starts at the first keyframe.
        let path = format!(
            "{CLOTH}\n[[collider]]\nkind = \"sphere\"\nradius = 0.1\npath = [[0, 1, 2, 3], [1, 1, 2, 4]]\nrepeat = true\n"
        );
        let scene = build(&path).expect("builds");
        let collider = scene.params.colliders[0];
        assert!(collider.path.is_some_and(|p| p.repeat));
        assert_eq!(collider.anchor(), DVec3::new(1.0, 2.0, 3.0));
        let backwards = path.replace("[1, 1, 2, 4]", "[0, 1, 2, 4]");
        let error = build(&backwards).unwrap_err().to_string();
        assert!(
            error.contains("collider[0].path: needs 2 to 8 keyframes"),
            "{error}"
        );
        let both = path.replace("repeat = true", "velocity = [1, 0, 0]");
        let error = build(&both).unwrap_err().to_string();
        assert!(
            error.contains("collider[0].velocity: a collider with a path"),
            "{error}"
        );
    }

    #[test]
    fn colliders_are_read_and_checked() {
        let text = format!(
            "{CLOTH}\n[collision]\nthickness = 0.01\n[[collider]]\nkind = \"sphere\"\ncenter = [0, -0.5, 0]\nradius = 0.3\nfriction = 0.2\n[[collider]]\nkind = \"plane\"\npoint = [0, -1, 0]\nnormal = [0, 2, 0]\n"
        );
        let scene = build(&text).expect("builds");
        assert_eq!(scene.params.colliders.len(), 2);
        assert_eq!(scene.params.collision_thickness, 0.01);
        assert!(
            matches!(scene.params.colliders[1].shape, Shape::Plane { normal, .. } if normal == DVec3::Y)
        );
        let bad = text.replace("radius = 0.3", "radius = -1");
        assert_eq!(
            build(&bad).unwrap_err().to_string(),
            "test.toml: collider[0].radius: must be a positive number, found -1"
        );
        let missing = text.replace("normal = [0, 2, 0]\n", "");
        assert!(
            build(&missing)
                .unwrap_err()
                .to_string()
                .contains("collider[1].normal")
        );
    }

    #[test]
    fn benchmark_scene_round_trips_through_toml() {
        let scene = SceneFile::benchmark(MeshSection::unit_grid(16, 16), 256);
        let parsed = SceneFile::parse(&scene.to_toml(), "bench").expect("parses");
        assert_eq!(parsed, scene);
    }
}
