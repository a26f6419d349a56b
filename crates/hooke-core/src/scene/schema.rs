//! The scene file's sections as serde types (the format: `scenes/README.md`).

use std::path::PathBuf;

use serde::{Deserialize, Deserializer, Serialize};

use crate::mesh::GridPlane;

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
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub bending: Option<BendingSection>,
    #[serde(default, rename = "handle", skip_serializing_if = "Vec::is_empty")]
    pub handles: Vec<HandleSection>,
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub tearing: Option<TearingSection>,
}

/// Springs that break, for good, when stretched too far (see `hooke_core::tearing`).
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct TearingSection {
    #[serde(default = "yes")]
    pub enabled: bool,
    /// A spring breaks when stretched past this many times its rest length (more than 1).
    pub max_stretch: f64,
}

/// Pinned vertices moved together by a path or a collider (see `hooke_core::handles`). Which
/// vertices: the keys of [`PinSection`], repeated here because serde cannot flatten a section
/// into one that refuses unknown keys.
#[derive(Clone, Debug, Default, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct HandleSection {
    #[serde(default, skip_serializing_if = "Vec::is_empty")]
    pub select: Vec<PinSelector>,
    #[serde(default, skip_serializing_if = "Vec::is_empty")]
    pub vertices: Vec<u32>,
    #[serde(default, skip_serializing_if = "Vec::is_empty")]
    pub boxes: Vec<PinBox>,
    /// Keyframes `[t, dx, dy, dz]`: the handle's displacement from where its vertices start.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub path: Option<Vec<[f64; 4]>>,
    /// Start the path over after its last keyframe.
    #[serde(default)]
    pub repeat: bool,
    /// Instead of a path: follow this collider (its index among the `[[collider]]`s).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub collider: Option<usize>,
}

impl HandleSection {
    /// The vertex selection, as a `[pins]` section.
    pub fn pins(&self) -> PinSection {
        PinSection {
            select: self.select.clone(),
            vertices: self.vertices.clone(),
            boxes: self.boxes.clone(),
        }
    }
}

/// Bending springs: one between the far vertices of every two triangles that share an edge.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct BendingSection {
    #[serde(default = "yes")]
    pub enabled: bool,
    /// Each bending spring's stiffness, N/m (times the material's stiffness maps).
    pub stiffness: f64,
    /// Each bending spring's own damping, N s/m: against the rate its length changes.
    #[serde(default)]
    pub damping: f64,
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
    /// The name of a per-vertex property of the mesh file (a PLY `property float mass`) that
    /// holds each vertex's mass in kg.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub property: Option<String>,
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
    /// The name of a per-vertex property of the mesh file (a PLY `property float stiffness`)
    /// that scales the stiffness: a spring's `D` is multiplied by the mean of its two ends'
    /// values, so a seam can be stiffer than the panel around it.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub stiffness_property: Option<String>,
    /// Boxes whose vertices' stiffness factor is multiplied by the box's `factor` (with the
    /// property's, if both are given): a spring's `D` is multiplied by the mean of its ends'.
    #[serde(
        default,
        rename = "stiffness_region",
        skip_serializing_if = "Vec::is_empty"
    )]
    pub stiffness_regions: Vec<StiffnessRegion>,
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

/// An axis-aligned box of the material with its own stiffness factor.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct StiffnessRegion {
    pub min: [f64; 3],
    pub max: [f64; 3],
    /// Multiplies the stiffness factor of every vertex inside (boundary included).
    pub factor: f64,
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
pub(super) fn default_gravity() -> [f64; 3] {
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
