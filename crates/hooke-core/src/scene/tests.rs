//! Scene parsing and building.

use std::path::Path;

use glam::DVec3;

use super::*;
use crate::collide::Shape;
use crate::tearing::Tearing;

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
    assert!(scene.material.dt < scene.max_stable_dt);
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
    assert_eq!(scene.material.dt, 0.5);
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
    let dynamics = scene.model.collision.colliders[0]
        .dynamics
        .expect("dynamic");
    assert_eq!((dynamics.mass, dynamics.restitution), (0.5, 0.3));
    assert_eq!(dynamics.force, DVec3::X);
    let config = scene
        .model
        .collision
        .self_collision
        .expect("self-collision");
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
        build(&capsule).expect("builds").model.collision.colliders[0].shape,
        Shape::Capsule { radius, .. } if radius == 0.1
    ));
    let error = build(&capsule.replace("end = [1, 0, 0]\n", ""))
        .unwrap_err()
        .to_string();
    assert!(error.contains("collider[0].end"), "{error}");
    let off = text.replace("grids = 3", "grids = 3\nenabled = false");
    assert!(
        build(&off)
            .expect("builds")
            .model
            .collision
            .self_collision
            .is_none()
    );
    // A keyframed path: the sphere starts at the first keyframe.
    let path = format!(
        "{CLOTH}\n[[collider]]\nkind = \"sphere\"\nradius = 0.1\npath = [[0, 1, 2, 3], [1, 1, 2, 4]]\nrepeat = true\n"
    );
    let scene = build(&path).expect("builds");
    let collider = scene.model.collision.colliders[0];
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
    assert_eq!(scene.model.collision.colliders.len(), 2);
    assert_eq!(scene.model.collision.thickness, 0.01);
    assert!(
        matches!(scene.model.collision.colliders[1].shape, Shape::Plane { normal, .. } if normal == DVec3::Y)
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

#[test]
fn keys_of_another_collider_kind_are_reported_not_ignored() {
    let sphere = format!(
        "{CLOTH}\n[[collider]]\nkind = \"sphere\"\ncenter = [0, -0.5, 0]\nradius = 0.3\nnormal = [0, 1, 0]\n"
    );
    assert_eq!(
        build(&sphere).unwrap_err().to_string(),
        "test.toml: collider[0].normal: does not apply to a sphere collider"
    );
    let plane = format!(
        "{CLOTH}\n[[collider]]\nkind = \"plane\"\npoint = [0, -1, 0]\nnormal = [0, 1, 0]\nradius = 2\n"
    );
    assert_eq!(
        build(&plane).unwrap_err().to_string(),
        "test.toml: collider[0].radius: does not apply to a plane collider"
    );
    let capsule = format!(
        "{CLOTH}\n[[collider]]\nkind = \"capsule\"\nstart = [0, -1, 0]\nend = [1, -1, 0]\nradius = 0.1\ncenter = [0, 0, 0]\n"
    );
    assert_eq!(
        build(&capsule).unwrap_err().to_string(),
        "test.toml: collider[0].center: does not apply to a capsule collider"
    );
}

#[test]
fn a_non_finite_centre_or_an_absurd_size_is_refused_naming_the_field() {
    // For a file mesh too (the check comes before the file is read).
    let file = "[mesh]\ngenerator = \"file\"\npath = \"cloth.obj\"\ncenter = [nan, 0, 0]\n\n[material]\nmass = { total = 1.0 }\nstiffness = 10.0\n";
    let error = build(file).unwrap_err().to_string();
    assert!(error.contains("mesh.center: must be finite"), "{error}");
    for size in ["[1e200, 1e200]", "[1e9, 1e-9]", "[1.0, 1e-7]", "[1e5, 1.0]"] {
        for generator in [
            "generator = \"grid\"\nresolution = [8, 8]",
            "generator = \"irregular\"\nvertices = 100",
        ] {
            let text = CLOTH.replace(
                "generator = \"grid\"\nresolution = [8, 8]",
                &format!("{generator}\nsize = {size}"),
            );
            let error = build(&text).unwrap_err().to_string();
            assert!(error.contains("mesh.size"), "{size}: {error}");
        }
    }
}

/// A unit square as ASCII PLY with `mass` and `stiffness` per vertex, and the scene around it.
fn scene_with_vertex_properties(material: &str) -> (tempfile::TempDir, std::path::PathBuf) {
    let dir = tempfile::tempdir().expect("tempdir");
    let ply = "ply\nformat ascii 1.0\nelement vertex 4\nproperty float x\nproperty float y\n\
               property float z\nproperty float mass\nproperty float stiffness\n\
               element face 2\nproperty list uchar int vertex_indices\nend_header\n\
               0 0 0 0.1 1\n1 0 0 0.2 3\n1 0 1 0.3 1\n0 0 1 0.4 1\n3 0 1 2\n3 0 2 3\n";
    std::fs::write(dir.path().join("square.ply"), ply).expect("mesh");
    let scene =
        format!("[mesh]\ngenerator = \"file\"\npath = \"square.ply\"\n[material]\n{material}\n");
    let path = dir.path().join("scene.toml");
    std::fs::write(&path, scene).expect("scene");
    (dir, path)
}

#[test]
fn masses_and_stiffness_factors_come_from_vertex_properties() {
    let (_dir, path) = scene_with_vertex_properties(
        "mass = { property = \"mass\" }\nstiffness = 10.0\nstiffness_property = \"stiffness\"",
    );
    let scene = SceneFile::load(&path)
        .and_then(|f| f.build(&path, false))
        .expect("builds");
    assert_eq!(
        scene.model.masses,
        vec![0.1f32 as f64, 0.2f32 as f64, 0.3f32 as f64, 0.4f32 as f64]
    );
    for (k, [a, b]) in scene.model.spring_ends.iter().enumerate() {
        // Vertex 1 is three times as stiff: its springs get the mean of 3 and 1.
        let expected = if *a == 1 || *b == 1 { 20.0 } else { 10.0 };
        assert_eq!(scene.model.stiffnesses[k], expected, "spring {a}-{b}");
    }
}

#[test]
fn a_missing_or_bad_vertex_property_names_the_field() {
    let (_dir, path) =
        scene_with_vertex_properties("mass = { property = \"density\" }\nstiffness = 10.0");
    let message = SceneFile::load(&path)
        .and_then(|f| f.build(&path, false))
        .unwrap_err()
        .to_string();
    assert!(
        message.ends_with(
            "material.mass.property: the mesh has no vertex property 'density' (it has: mass, stiffness)"
        ),
        "{message}"
    );
    let (_dir, path) = scene_with_vertex_properties(
        "mass = { total = 1.0, property = \"mass\" }\nstiffness = 10.0",
    );
    let message = SceneFile::load(&path)
        .and_then(|f| f.build(&path, false))
        .unwrap_err()
        .to_string();
    assert!(message.contains("exactly one of"), "{message}");
    let message = build(&CLOTH.replace(
        "damping = 0.01",
        "damping = 0.01\nstiffness_property = \"k\"",
    ))
    .unwrap_err()
    .to_string();
    assert!(
        message.contains(
            "material.stiffness_property: the mesh has no vertex property 'k' (it has none"
        ),
        "{message}"
    );
}

#[test]
fn bending_adds_a_spring_across_every_interior_edge() {
    let plain = build(CLOTH).expect("builds");
    let text = format!("{CLOTH}\n[bending]\nstiffness = 20.0\n");
    let bent = build(&text).expect("builds");
    let interior = plain
        .mesh
        .edges()
        .iter()
        .filter(|e| e.triangle_count == 2)
        .count();
    assert_eq!(bent.model.bending_springs, interior);
    assert_eq!(
        bent.model.spring_count(),
        plain.model.spring_count() + interior
    );
    let first = plain.model.spring_count();
    assert!(!bent.model.is_bending(first - 1) && bent.model.is_bending(first));
    assert!(bent.model.stiffnesses[first..].iter().all(|k| *k == 20.0));
    // More springs per vertex: a smaller stable time step.
    assert!(bent.max_stable_dt < plain.max_stable_dt);
    let off = format!("{CLOTH}\n[bending]\nenabled = false\nstiffness = 20.0\n");
    assert_eq!(build(&off).expect("builds").model, plain.model);
    assert_eq!(
        build(&text.replace("stiffness = 20.0", "stiffness = 0"))
            .unwrap_err()
            .to_string(),
        "test.toml: bending.stiffness: must be a positive number, found 0"
    );
    // Their own dampers: in the model, and counted by the stability bound.
    let damped = build(&format!("{text}damping = 0.05\n")).expect("builds");
    assert_eq!(damped.model.bending_damping, 0.05);
    assert!(damped.max_stable_dt < bent.max_stable_dt);
    assert_eq!(
        build(&format!("{text}damping = -1\n"))
            .unwrap_err()
            .to_string(),
        "test.toml: bending.damping: must be zero or positive, found -1"
    );
}

#[test]
fn a_stiffness_region_scales_the_springs_of_its_vertices() {
    // The grid spans -0.5..0.5 in x and z; the region holds the row at z = -0.5.
    let region =
        "[[material.stiffness_region]]\nmin = [-1, -1, -0.6]\nmax = [1, 1, -0.45]\nfactor = 3.0\n";
    let scene = build(&format!("{CLOTH}\n{region}")).expect("builds");
    let model = &scene.model;
    let inside = |v: u32| scene.mesh.positions[v as usize].z < -0.45;
    for (s, [a, b]) in model.spring_ends.iter().enumerate() {
        let expected = 200.0
            * match (inside(*a), inside(*b)) {
                (true, true) => 3.0,
                (false, false) => 1.0,
                _ => 2.0,
            };
        assert!(
            (model.stiffnesses[s] - expected).abs() < 1e-12,
            "spring {s}"
        );
    }
    assert_eq!(
        build(&format!("{CLOTH}\n{}", region.replace("3.0", "-2")))
            .unwrap_err()
            .to_string(),
        "test.toml: material.stiffness_region[0].factor: must be a positive number, found -2"
    );
    assert_eq!(
        build(&format!(
            "{CLOTH}\n{}",
            region.replace("-0.6]", "4]").replace("-0.45]", "5]")
        ))
        .unwrap_err()
        .to_string(),
        "test.toml: material.stiffness_region[0]: contains no vertex"
    );
}

#[test]
fn every_key_of_the_scene_format_page_parses() {
    let page = include_str!("../../../../scenes/README.md");
    let keys = page
        .split("## Every key")
        .nth(1)
        .and_then(|rest| rest.split("```toml\n").nth(1))
        .and_then(|block| block.split("```").next())
        .expect("the page's key listing");
    let file = SceneFile::parse(keys, "scenes/README.md").unwrap_or_else(|e| panic!("{e}"));
    assert!(file.bending.is_some() && !file.material.stiffness_regions.is_empty());
    assert_eq!(file.handles.len(), 1);
    assert!(file.tearing.is_some());
}

#[test]
fn tearing_takes_a_stretch_above_one_and_names_the_field_otherwise() {
    let scene = build(&format!(
        "{CLOTH}
[tearing]
max_stretch = 1.4
"
    ))
    .expect("builds");
    assert_eq!(scene.model.tearing, Some(Tearing { max_stretch: 1.4 }));
    let off = build(&format!(
        "{CLOTH}
[tearing]
enabled = false
max_stretch = 1.4
"
    ));
    assert_eq!(off.expect("builds").model.tearing, None);
    for bad in ["1.0", "0.5", "-2", "inf"] {
        let error = build(&format!(
            "{CLOTH}
[tearing]
max_stretch = {bad}
"
        ))
        .unwrap_err()
        .to_string();
        assert!(
            error.starts_with("test.toml: tearing.max_stretch: must be a number above 1"),
            "{error}"
        );
    }
    let error = build(&format!(
        "{CLOTH}
[tearing]
stretch = 1.4
"
    ))
    .unwrap_err()
    .to_string();
    assert!(error.contains("unknown field `stretch`"), "{error}");
}

#[test]
fn handles_pin_their_vertices_and_name_their_errors() {
    let handle = "[[handle]]\nselect = [\"corners\"]\npath = [[0, 0, 0, 0], [1, 0.2, 0, 0]]\n";
    let scene = build(&format!("{CLOTH}\n{handle}")).expect("builds");
    let handles = &scene.model.handles;
    assert_eq!(handles.len(), 1);
    assert_eq!(handles[0].vertices, [0, 7, 56, 63]);
    assert!(
        handles[0]
            .vertices
            .iter()
            .all(|v| scene.model.pinned[*v as usize])
    );
    let error = |text: String| build(&format!("{CLOTH}\n{text}")).unwrap_err().to_string();
    assert_eq!(
        error(handle.replace("path = [[0, 0, 0, 0], [1, 0.2, 0, 0]]", "collider = 0")),
        "test.toml: handle[0].collider: collider 0 does not exist (the scene has 0)"
    );
    assert_eq!(
        error(format!("{handle}collider = 0\n")),
        "test.toml: handle[0]: give exactly one of path (keyframes [t, dx, dy, dz]) or collider (an index)"
    );
    assert_eq!(
        error(handle.replace("[1, 0.2, 0, 0]", "[0, 0.2, 0, 0]")),
        "test.toml: handle[0].path: needs 2 to 8 keyframes [t, x, y, z] with increasing t, found 2"
    );
    assert_eq!(
        error(handle.replace("select = [\"corners\"]", "vertices = [64]")),
        "test.toml: handle[0].vertices: vertex 64 does not exist (mesh has 64 vertices)"
    );
    assert_eq!(
        error(handle.replace("select = [\"corners\"]\n", "")),
        "test.toml: handle[0]: holds no vertex: give vertices, select or boxes"
    );
}
