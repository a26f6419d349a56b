//! Meshes from files keep the file's vertex numbering end to end: `hooke run` on an OBJ, an
//! ASCII PLY and a binary PLY whose faces list vertices out of order writes vertex `i` of the file
//! as vertex `i` of its output, pins by index hold exactly the named vertices, and a vertex no
//! face uses is kept as a free point mass.

use std::path::Path;
use std::process::Command;

use glam::DVec3;
use hooke_core::mesh::{load_mesh, read_ply_state};

/// Columns and rows of the grid the test mesh is cut from.
const SIDE: usize = 4;
/// Where the unused vertex sits in the file: among the others, so that numbering after it counts.
const FREE_VERTEX: usize = 3;
/// Two vertices pinned by index in the scene (neither the free one).
const PINNED: [usize; 2] = [0, 10];

/// A scrambled mesh: a 4 x 4 grid whose vertices are listed in a permuted order with a free
/// vertex among them, and whose faces come in reverse order with rotated corners. Every
/// coordinate is a multiple of 1/8, exact in float32 and in decimal.
struct Scrambled {
    positions: Vec<DVec3>,
    triangles: Vec<[u32; 3]>,
}

fn scrambled() -> Scrambled {
    let grid_vertex =
        |i: usize| DVec3::new((i % SIDE) as f64 * 0.25, 1.0, (i / SIDE) as f64 * 0.25);
    // Grid vertex i goes to file slot (7 i mod 16), skipping the free vertex's slot.
    let count = SIDE * SIDE;
    let mut file_of_grid = vec![0u32; count];
    let mut positions = vec![DVec3::ZERO; count + 1];
    for (i, slot) in file_of_grid.iter_mut().enumerate() {
        let mut file = (7 * i) % count;
        if file >= FREE_VERTEX {
            file += 1;
        }
        *slot = file as u32;
        positions[file] = grid_vertex(i);
    }
    positions[FREE_VERTEX] = DVec3::new(2.0, 3.0, -1.0);
    let mut triangles = Vec::new();
    for row in 0..SIDE - 1 {
        for column in 0..SIDE - 1 {
            let at = |r: usize, c: usize| file_of_grid[r * SIDE + c];
            let (a, b, c, d) = (
                at(row, column),
                at(row, column + 1),
                at(row + 1, column + 1),
                at(row + 1, column),
            );
            triangles.push([a, b, c]);
            triangles.push([c, d, a]);
        }
    }
    triangles.reverse();
    for (k, t) in triangles.iter_mut().enumerate() {
        t.rotate_left(k % 3);
    }
    Scrambled {
        positions,
        triangles,
    }
}

fn write_obj(mesh: &Scrambled, path: &Path) {
    let mut text = String::from("# scrambled test mesh\no sheet\n");
    for p in &mesh.positions {
        text += &format!("v {} {} {}\n", p.x, p.y, p.z);
    }
    text += "vt 0 0\nvn 0 1 0\n";
    // Every corner form, and negative indices, name the same vertices.
    for (k, t) in mesh.triangles.iter().enumerate() {
        let n = mesh.positions.len() as i64;
        let corner = |i: u32| match k % 4 {
            0 => format!("{}", i + 1),
            1 => format!("{}/1/1", i + 1),
            2 => format!("{}//1", i + 1),
            _ => format!("{}", i64::from(i) - n),
        };
        text += &format!("f {} {} {}\n", corner(t[0]), corner(t[1]), corner(t[2]));
    }
    std::fs::write(path, text).expect("write obj");
}

fn ply_header(format: &str, mesh: &Scrambled) -> String {
    format!(
        "ply\nformat {format} 1.0\ncomment scrambled test mesh\nelement vertex {}\n\
         property float x\nproperty float y\nproperty float z\nelement face {}\n\
         property list uchar int vertex_indices\nend_header\n",
        mesh.positions.len(),
        mesh.triangles.len()
    )
}

fn write_ascii_ply(mesh: &Scrambled, path: &Path) {
    let mut text = ply_header("ascii", mesh);
    for p in &mesh.positions {
        text += &format!("{} {} {}\n", p.x, p.y, p.z);
    }
    for t in &mesh.triangles {
        text += &format!("3 {} {} {}\n", t[0], t[1], t[2]);
    }
    std::fs::write(path, text).expect("write ascii ply");
}

fn write_binary_ply(mesh: &Scrambled, path: &Path) {
    let mut bytes = ply_header("binary_little_endian", mesh).into_bytes();
    for p in &mesh.positions {
        for value in p.to_array() {
            bytes.extend_from_slice(&(value as f32).to_le_bytes());
        }
    }
    for t in &mesh.triangles {
        bytes.push(3);
        for i in t {
            bytes.extend_from_slice(&(*i as i32).to_le_bytes());
        }
    }
    std::fs::write(path, bytes).expect("write binary ply");
}

fn write_scene(dir: &Path, mesh_file: &str) -> std::path::PathBuf {
    let scene = format!(
        "[mesh]\ngenerator = \"file\"\npath = \"{mesh_file}\"\n\n\
         [material]\nmass = {{ per_vertex = 0.01 }}\nstiffness = 50.0\n\n\
         [pins]\nvertices = [{}, {}]\n\n[simulation]\nsteps = 10\n",
        PINNED[0], PINNED[1]
    );
    let path = dir.join(format!("{mesh_file}.toml"));
    std::fs::write(&path, scene).expect("write scene");
    path
}

/// Runs `hooke run` and returns the output folder.
fn run(scene: &Path, steps: &str, backend: &str, out: &Path) {
    let result = Command::new(env!("CARGO_BIN_EXE_hooke"))
        .args(["run", scene.to_str().expect("utf-8")])
        .args([
            "--steps",
            steps,
            "--backend",
            backend,
            "--no-frames",
            "--output",
        ])
        .arg(out)
        .output()
        .expect("hooke runs");
    assert!(
        result.status.success(),
        "{}",
        String::from_utf8_lossy(&result.stderr)
    );
}

/// The time step a run used, from `final-state.toml`.
fn dt_of(out: &Path) -> f64 {
    let sidecar = std::fs::read_to_string(out.join("final-state.toml")).expect("sidecar");
    sidecar
        .lines()
        .find_map(|l| l.strip_prefix("dt = "))
        .and_then(|v| v.trim().parse().ok())
        .expect("dt in the sidecar")
}

#[test]
fn every_mesh_format_keeps_the_files_vertex_order_pins_and_free_vertices() {
    let dir = tempfile::tempdir().expect("tempdir");
    let mesh = scrambled();
    write_obj(&mesh, &dir.path().join("sheet.obj"));
    write_ascii_ply(&mesh, &dir.path().join("sheet-ascii.ply"));
    write_binary_ply(&mesh, &dir.path().join("sheet-binary.ply"));
    for file in ["sheet.obj", "sheet-ascii.ply", "sheet-binary.ply"] {
        let scene = write_scene(dir.path(), file);

        // 0 steps: the output is the input, vertex for vertex and face for face.
        let out = dir.path().join(format!("{file}-0"));
        run(&scene, "0", "cpu", &out);
        let state = read_ply_state(&out.join("final-state.ply")).expect("state");
        assert_eq!(state.positions, mesh.positions, "{file}: vertex order");
        let (written, _) = load_mesh(&out.join("final-state.ply")).expect("state as a mesh");
        assert_eq!(written.triangles, mesh.triangles, "{file}: faces");

        // Pins by index hold exactly the named vertices; every other vertex moves.
        let out = dir.path().join(format!("{file}-cpu"));
        run(&scene, "200", "cpu", &out);
        let state = read_ply_state(&out.join("final-state.ply")).expect("state");
        for (i, (now, start)) in state.positions.iter().zip(&mesh.positions).enumerate() {
            if PINNED.contains(&i) {
                assert_eq!(now, start, "{file}: pinned vertex {i} moved");
            } else {
                assert!(now.y < start.y - 1e-3, "{file}: vertex {i} did not fall");
            }
        }

        // The free vertex falls as Verlet integrates gravity from rest: after n steps it has
        // dropped g dt^2 n (n + 1) / 2 (-> g t^2 / 2), on the float64 reference.
        let out = dir.path().join(format!("{file}-reference"));
        run(&scene, "200", "reference", &out);
        let state = read_ply_state(&out.join("final-state.ply")).expect("state");
        let dt = dt_of(&out);
        let drop = 9.81 * dt * dt * 200.0 * 201.0 / 2.0;
        let fallen = mesh.positions[FREE_VERTEX].y - state.positions[FREE_VERTEX].y;
        // Float64 sums of 200 increments: exact to far better than 1e-9 relative.
        assert!(
            (fallen - drop).abs() < 1e-9 * drop,
            "{file}: free vertex fell {fallen}, expected {drop}"
        );
        assert_eq!(
            (
                state.positions[FREE_VERTEX].x,
                state.positions[FREE_VERTEX].z
            ),
            (2.0, -1.0),
            "{file}: the free vertex only falls"
        );
    }
}
