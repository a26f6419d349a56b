//! Loading a scene file for a command, reporting mesh warnings once.

use std::path::Path;

use hooke_core::scene::{Scene, SceneFile};

pub fn load_scene(path: &Path, allow_unstable: bool) -> anyhow::Result<Scene> {
    let scene = SceneFile::load(path)?.build(path, allow_unstable)?;
    for warning in &scene.mesh_warnings {
        eprintln!("warning: {}: {warning}", path.display());
    }
    if scene.material.dt > scene.max_stable_dt {
        eprintln!(
            "warning: dt {:.3e} s exceeds the stability bound {:.3e} s; the run may blow up",
            scene.material.dt, scene.max_stable_dt
        );
    }
    Ok(scene)
}
