//! Scene files: a TOML description of a mesh, its material, pins, forces, colliders and run
//! settings.
//!
//! Parsing rejects unknown keys and wrong types with the file, line and key (from `toml`);
//! [`SceneFile::build`] then checks ranges and names the offending field. See `scenes/README.md`
//! for the format with an example of every key.
//!
//! - `schema`: the file's sections as serde types;
//! - `build`: checks, mesh, pins, model, time step;
//! - `inputs`: the scene's control (wind, forces, drags) and collision set-up (colliders,
//!   self-collision);
//! - `selectors`: named vertex selections (`corners`, `top-edge`, ...).

mod build;
mod inputs;
mod schema;
mod selectors;
#[cfg(test)]
mod tests;

use std::path::Path;

pub use schema::*;
pub use selectors::select_vertices;

use crate::mesh::{self, Mesh, MeshWarning};
use crate::{Control, Material, Model};

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
    /// The model, its colliders and self-collision set-up included.
    pub model: Model,
    pub material: Material,
    /// The scene's own per-step inputs: wind, point forces, drags.
    pub control: Control,
    pub steps: u64,
    pub frame_every: u64,
    /// The stability bound on dt for this model, s.
    pub max_stable_dt: f64,
}

impl SceneFile {
    /// Reads and parses a scene file (no range checks yet; see [`SceneFile::build`]).
    pub fn load(path: &Path) -> Result<Self, SceneError> {
        let text = crate::input_file::read_to_string(path).map_err(|source| SceneError::Io {
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
                stiffness_property: None,
                stiffness_regions: Vec::new(),
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
                gravity: schema::default_gravity(),
                frame_every: 100,
            },
            wind: None,
            forces: Vec::new(),
            drags: Vec::new(),
            colliders: Vec::new(),
            collision: None,
            self_collision: None,
            bending: None,
            handles: Vec::new(),
            tearing: None,
        }
    }
}

/// `Ok` if `condition` holds, else the error `error` makes.
fn require(condition: bool, error: impl FnOnce() -> SceneError) -> Result<(), SceneError> {
    if condition { Ok(()) } else { Err(error()) }
}
