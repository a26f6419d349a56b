//! A run's state on disk, so it can continue: `NAME.ply` holds float64 `x` and `x_prev` per
//! vertex with the faces (any PLY tool reads it), and `NAME.toml` beside it what a PLY cannot
//! hold: the step counter (which places scripted colliders), the time step, and each dynamic
//! ball's place, velocity and spin, and the springs torn so far. Both are written through a temporary file and a rename.

use std::path::{Path, PathBuf};

use glam::DVec3;
use hooke_core::atomic_file::write_atomically;
use hooke_core::collide::Shape;
use hooke_core::mesh::{MeshLoadError, read_ply_state, write_ply_state};
use hooke_core::{Model, Snapshot};
use serde::{Deserialize, Serialize};

/// What the PLY cannot hold.
#[derive(Debug, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
struct Sidecar {
    /// Steps taken when the state was saved.
    steps_taken: u64,
    /// The time step it was taken with, s.
    dt: f64,
    vertices: usize,
    #[serde(default, rename = "ball")]
    balls: Vec<Ball>,
    /// The springs torn so far (spring indices, as `hooke info` counts springs).
    #[serde(default, skip_serializing_if = "Vec::is_empty")]
    broken_springs: Vec<u32>,
}

/// A dynamic ball as it was.
#[derive(Debug, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
struct Ball {
    /// Index of the `[[collider]]` entry.
    collider: usize,
    center: [f64; 3],
    velocity: [f64; 3],
    spin: [f64; 3],
}

/// A state file could not be written or does not fit the scene.
#[derive(Debug, thiserror::Error)]
pub enum StateFileError {
    #[error("{path}: {source}")]
    Io {
        path: String,
        source: std::io::Error,
    },
    #[error(transparent)]
    Ply(#[from] MeshLoadError),
    #[error("{path}: {message}")]
    Invalid { path: String, message: String },
}

/// The sidecar of `ply`: the same path ending in `.toml`.
pub fn sidecar_path(ply: &Path) -> PathBuf {
    ply.with_extension("toml")
}

/// Writes `snapshot` of `model`, stepped with `dt`, as `ply` and its sidecar.
pub fn save_state(
    ply: &Path,
    snapshot: &Snapshot,
    model: &Model,
    dt: f64,
) -> Result<(), StateFileError> {
    let io = |path: &Path| {
        let path = path.display().to_string();
        move |source| StateFileError::Io { path, source }
    };
    let state = &snapshot.state;
    write_ply_state(
        ply,
        &state.positions,
        &state.previous_positions,
        &model.triangles,
    )
    .map_err(io(ply))?;
    let balls = snapshot
        .colliders
        .iter()
        .enumerate()
        .filter(|(_, c)| c.dynamics.is_some())
        .filter_map(|(collider, c)| match c.shape {
            Shape::Sphere { center, .. } => Some(Ball {
                collider,
                center: center.to_array(),
                velocity: c.velocity.to_array(),
                spin: c.spin.to_array(),
            }),
            Shape::Plane { .. } | Shape::Capsule { .. } => None,
        })
        .collect();
    let sidecar = Sidecar {
        steps_taken: snapshot.steps_taken,
        dt,
        vertices: state.positions.len(),
        balls,
        broken_springs: snapshot.broken_springs.clone(),
    };
    let path = sidecar_path(ply);
    let text = toml::to_string(&sidecar).map_err(|e| StateFileError::Invalid {
        path: path.display().to_string(),
        message: e.to_string(),
    })?;
    write_atomically(&path, |file| file.write_all(text.as_bytes())).map_err(io(&path))
}

/// Reads `ply` and its sidecar as a snapshot of `model` to continue with time step `dt`. A
/// state of another mesh, another dt or other balls is refused with the reason.
pub fn load_state(ply: &Path, model: &Model, dt: f64) -> Result<Snapshot, StateFileError> {
    let path = sidecar_path(ply);
    let name = path.display().to_string();
    let invalid = |message: String| StateFileError::Invalid {
        path: name.clone(),
        message,
    };
    let text =
        hooke_core::input_file::read_to_string(&path).map_err(|source| StateFileError::Io {
            path: name.clone(),
            source,
        })?;
    let sidecar: Sidecar = toml::from_str(&text).map_err(|e| invalid(e.to_string()))?;
    let state = read_ply_state(ply)?;
    let n = model.vertex_count();
    if state.positions.len() != n || sidecar.vertices != n {
        return Err(StateFileError::Invalid {
            path: ply.display().to_string(),
            message: format!(
                "the state has {} vertices, the scene's mesh {n}",
                state.positions.len()
            ),
        });
    }
    if (sidecar.dt - dt).abs() > 1e-12 * dt.abs() {
        return Err(invalid(format!(
            "the state was saved at dt = {:e} s and the scene steps with dt = {dt:e} s; scripted colliders and balls would jump in time (resume with the same dt)",
            sidecar.dt
        )));
    }
    let mut colliders = model.collision.colliders.clone();
    for ball in &sidecar.balls {
        let collider = colliders
            .get_mut(ball.collider)
            .filter(|c| c.dynamics.is_some())
            .ok_or_else(|| {
                invalid(format!(
                    "ball {}: the scene has no dynamic ball at that collider index",
                    ball.collider
                ))
            })?;
        if let Shape::Sphere { center, .. } = &mut collider.shape {
            *center = DVec3::from_array(ball.center);
        }
        collider.velocity = DVec3::from_array(ball.velocity);
        collider.spin = DVec3::from_array(ball.spin);
    }
    let saved_balls = sidecar.balls.len();
    let scene_balls = colliders.iter().filter(|c| c.dynamics.is_some()).count();
    if saved_balls != scene_balls {
        return Err(invalid(format!(
            "the state has {saved_balls} dynamic balls, the scene {scene_balls}"
        )));
    }
    if let Some(&spring) = sidecar
        .broken_springs
        .iter()
        .find(|&&s| s as usize >= model.spring_count())
    {
        return Err(invalid(format!(
            "broken_springs: spring {spring} does not exist (the scene has {} springs)",
            model.spring_count()
        )));
    }
    Ok(Snapshot {
        state,
        colliders,
        steps_taken: sidecar.steps_taken,
        broken_springs: sidecar.broken_springs,
    })
}
