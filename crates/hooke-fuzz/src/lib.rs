//! The fuzzing harness of hooke's front door: what each fuzz target does with one input. The
//! cargo-fuzz project in `fuzz/` calls these functions from libFuzzer; keeping them in the
//! workspace lets `cargo test` replay the seeds (`fuzz/seeds/`) and every input that ever
//! crashed a reader (`fuzz/regressions/`) through exactly the same code.
//!
//! An input passes when the reader returns, `Ok` or `Err`: a panic, a hang or an unbounded
//! allocation is a bug. What a reader accepts goes on through validation, the model build and
//! the stability bound, as `hooke run` would take it.

use std::path::Path;

use hooke_core::mesh::{Mesh, MeshFormat, parse_mesh};
use hooke_core::scene::{MeshGenerator, SceneFile};
use hooke_core::{MassModel, Model, ModelOptions, StiffnessModel};

/// Generated meshes above this many vertices are parsed and validated but not built: a scene
/// may rightly ask for 8192 x 8192 vertices, which takes seconds and gigabytes, not a bug.
pub const MAX_FUZZ_VERTICES: u64 = 20_000;

/// A fuzz target: takes one input, returns if the input is handled, panics on a bug.
pub type Target = fn(&[u8]);

/// The targets by name, as `fuzz/fuzz_targets/` and the seed folders name them.
pub const TARGETS: [(&str, Target); 3] = [("obj", obj), ("ply", ply), ("scene", scene)];

/// An OBJ file.
pub fn obj(data: &[u8]) {
    mesh(data, MeshFormat::Obj, "fuzz.obj");
}

/// A PLY file, ASCII or binary.
pub fn ply(data: &[u8]) {
    mesh(data, MeshFormat::Ply, "fuzz.ply");
}

/// A scene file. A mesh file it names is looked for beside `/nonexistent/fuzz.toml`, so relative
/// paths find nothing; the mesh readers have their own targets.
pub fn scene(data: &[u8]) {
    let Ok(text) = std::str::from_utf8(data) else {
        return;
    };
    let Ok(file) = SceneFile::parse(text, "fuzz.toml") else {
        return;
    };
    let vertices = match file.mesh.generator {
        MeshGenerator::Grid => file
            .mesh
            .resolution
            .map_or(0, |[c, r]| u64::from(c) * u64::from(r)),
        MeshGenerator::Irregular => file.mesh.vertices.map_or(0, u64::from),
        MeshGenerator::File => 0,
    };
    if vertices <= MAX_FUZZ_VERTICES {
        // The build checks every range, makes the model and checks dt against the bound.
        let _ = file.build(Path::new("/nonexistent/fuzz.toml"), false);
    }
}

fn mesh(data: &[u8], format: MeshFormat, name: &str) {
    if let Ok((mesh, _warnings)) = parse_mesh(data, format, name) {
        model(&mesh);
    }
}

/// Builds the model a scene would and its stability bound: springs, masses and the valence
/// tables must cope with whatever a valid file holds.
fn model(mesh: &Mesh) {
    for mass in [MassModel::TotalUniform(1.0), MassModel::AreaDensity(0.2)] {
        let options = ModelOptions {
            stiffness: StiffnessModel::InverseRestLength(10.0),
            mass,
            rest_length_scale: 1.0,
            pinned: vec![0],
        };
        if let Ok(model) = Model::from_mesh(mesh, &options) {
            let _ = hooke_core::stability::stability_limit(&model, 0.01);
        }
    }
}
