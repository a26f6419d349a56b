"""`hooke run --output-format`: the OBJ sequence and the Blender point cache, read back by
readers that are not hooke's (trimesh for OBJ, a few lines of numpy for .pc2), equal the run's
binary PLY frames in the mesh file's vertex order."""

import subprocess
from pathlib import Path

import numpy as np
import numpy.typing as npt
import pytest
import trimesh
from conftest import ROOT, hooke_binary, run_cli

import hooke

SIDE = 6
STEPS = 120
EVERY = 40
FRAMES = STEPS // EVERY + 1


def shuffled_sheet(tmp_path: Path) -> tuple[Path, npt.NDArray[np.int64]]:
    """A 6 x 6 sheet written as OBJ with its vertices in a random order; returns the scene
    and, for each file vertex, its place in the grid."""
    rng = np.random.default_rng(7)
    u, v = np.meshgrid(np.linspace(0.0, 1.0, SIDE), np.linspace(0.0, 1.0, SIDE))
    grid = np.stack([u.ravel(), np.ones(SIDE * SIDE), v.ravel()], axis=1)
    quads = [
        (r * SIDE + c, r * SIDE + c + 1, (r + 1) * SIDE + c)
        for r in range(SIDE - 1)
        for c in range(SIDE - 1)
    ]
    quads += [
        (r * SIDE + c + 1, (r + 1) * SIDE + c + 1, (r + 1) * SIDE + c)
        for r in range(SIDE - 1)
        for c in range(SIDE - 1)
    ]
    order = rng.permutation(SIDE * SIDE)  # file vertex i is grid vertex order[i]
    file_index = np.argsort(order)
    lines = [f"v {x} {y} {z}" for x, y, z in grid[order]]
    lines += [f"f {' '.join(str(file_index[k] + 1) for k in q)}" for q in quads]
    (tmp_path / "sheet.obj").write_text("\n".join(lines) + "\n")
    corners = [int(file_index[0]), int(file_index[SIDE - 1])]
    scene = tmp_path / "scene.toml"
    scene.write_text(
        f'[mesh]\ngenerator = "file"\npath = "sheet.obj"\n'
        f"[material]\nmass = {{ total = 0.05 }}\nstiffness = 50.0\ndamping = 0.001\n"
        f"[pins]\nvertices = {corners}\n"
        f'[simulation]\ndt = "auto"\nsteps = {STEPS}\nframe_every = {EVERY}\n'
    )
    return scene, order


def grid_triangles(n: int) -> npt.NDArray[np.int64]:
    """The triangles of an n x n grid numbered row by row, two per quad."""
    return np.array(
        [
            t
            for r in range(n - 1)
            for c in range(n - 1)
            for t in (
                (r * n + c, (r + 1) * n + c, (r + 1) * n + c + 1),
                (r * n + c, (r + 1) * n + c + 1, r * n + c + 1),
            )
        ]
    )


def ply_positions(path: Path) -> npt.NDArray[np.float32]:
    """Positions of a binary PLY frame (float32 x, y, z, then maybe s, t, per vertex)."""
    data = path.read_bytes()
    end = data.index(b"end_header\n") + len(b"end_header\n")
    header = data[:end].decode("ascii").splitlines()
    start = next(k for k, line in enumerate(header) if line.startswith("element vertex"))
    count = int(header[start].split()[2])
    properties = []
    for line in header[start + 1 :]:
        if not line.startswith("property"):
            break
        properties.append(line.split())
    assert all(p[1] == "float" for p in properties) and properties[0][2] == "x"
    width = len(properties)
    vertices = np.frombuffer(data, dtype="<f4", count=width * count, offset=end)
    return vertices.reshape(count, width)[:, :3]


def read_pc2(path: Path) -> npt.NDArray[np.float32]:
    """Blender's point cache: a 32-byte header, then float32 x y z per point per sample."""
    data = path.read_bytes()
    assert data[:12] == b"POINTCACHE2\0"
    version, points = np.frombuffer(data, "<i4", 2, 12)
    start, rate = np.frombuffer(data, "<f4", 2, 20)
    (samples,) = np.frombuffer(data, "<i4", 1, 28)
    assert (version, start, rate) == (1, 1.0, 1.0)
    assert len(data) == 32 + 12 * points * samples
    return np.frombuffer(data, "<f4", offset=32).reshape(samples, points, 3)


def run(scene: Path, out: Path, fmt: str) -> list[Path]:
    run_cli("run", str(scene), "--output", str(out), "--output-format", fmt)
    return sorted(out.iterdir())


def test_obj_sequence_and_pc2_equal_the_ply_frames_in_file_order(tmp_path: Path) -> None:
    scene, order = shuffled_sheet(tmp_path)
    ply = [p for p in run(scene, tmp_path / "ply", "ply") if p.name.startswith("frame-")]
    assert [p.name for p in ply] == [f"frame-{k * EVERY:07}.ply" for k in range(FRAMES)]
    frames = [ply_positions(p) for p in ply]
    # Vertex order is the file's: frame 0 is the file's own vertices.
    u, v = np.meshgrid(np.linspace(0.0, 1.0, SIDE), np.linspace(0.0, 1.0, SIDE))
    grid = np.stack([u.ravel(), np.ones(SIDE * SIDE), v.ravel()], axis=1)
    np.testing.assert_allclose(frames[0], grid[order], atol=1e-7)
    assert np.abs(frames[-1] - frames[0]).max() > 1e-3, "the sheet moved"

    objs = [p for p in run(scene, tmp_path / "obj", "obj") if p.suffix == ".obj"]
    assert [p.name for p in objs] == [p.with_suffix(".obj").name for p in ply]
    faces = None
    for obj, expected in zip(objs, frames, strict=True):
        mesh = trimesh.load_mesh(obj, process=False)
        np.testing.assert_array_equal(np.asarray(mesh.vertices, dtype=np.float32), expected)
        normals = np.asarray(mesh.vertex_normals)
        np.testing.assert_allclose(np.linalg.norm(normals, axis=1), 1.0, atol=1e-5)
        faces = np.asarray(mesh.faces) if faces is None else faces
        np.testing.assert_array_equal(np.asarray(mesh.faces), faces)

    out = tmp_path / "pc2"
    run(scene, out, "pc2")
    cache = read_pc2(out / "frames.pc2")
    assert cache.shape == (FRAMES, SIDE * SIDE, 3)
    for sample, expected in zip(cache, frames, strict=True):
        np.testing.assert_array_equal(sample, expected)
    assert not list(out.glob(".*.partial")), "no temporary left"


def test_an_unknown_format_is_refused_with_the_choices() -> None:
    scene = ROOT / "scenes" / "cloth-pinned.toml"
    result = subprocess.run(
        [str(hooke_binary()), "run", str(scene), "--output-format", "fbx"],
        capture_output=True,
        text=True,
        check=False,
    )
    assert result.returncode != 0
    assert "expected one of ply, obj, pc2" in result.stderr


@pytest.mark.parametrize("fmt", ["obj", "pc2"])
def test_no_frames_writes_no_frame_files(tmp_path: Path, fmt: str) -> None:
    scene, _ = shuffled_sheet(tmp_path)
    run_cli(
        "run", str(scene), "--output", str(tmp_path / "o"), "--output-format", fmt, "--no-frames"
    )
    names = sorted(p.name for p in (tmp_path / "o").iterdir())
    assert names == ["final-state.ply", "final-state.toml", "summary.json"]


def test_python_frame_writer_equals_the_cli_frames(tmp_path: Path) -> None:
    scene, _ = shuffled_sheet(tmp_path)
    cli = tmp_path / "cli"
    run_cli("run", str(scene), "--output", str(cli / "cloth.pc2"), "--backend", "cpu")
    expected = read_pc2(cli / "cloth.pc2")

    sim = hooke.Simulation.from_scene(scene, backend="cpu")
    with hooke.FrameWriter(sim, tmp_path / "py.pc2", frame_every=EVERY) as frames:
        frames.write()
        for _ in range(STEPS // EVERY):
            sim.step(EVERY)
            frames.write()
        assert not (tmp_path / "py.pc2").exists(), "the file appears when closed"
    np.testing.assert_array_equal(read_pc2(tmp_path / "py.pc2"), expected)

    sim = hooke.Simulation.from_scene(scene, backend="cpu")
    writer = hooke.FrameWriter(sim, tmp_path / "objs", format="obj")
    writer.write()
    sim.step(STEPS)
    writer.write()
    assert writer.close() == 2
    last = trimesh.load_mesh(tmp_path / "objs" / f"frame-{STEPS:07}.obj", process=False)
    np.testing.assert_array_equal(np.asarray(last.vertices, dtype=np.float32), expected[-1])


def test_python_frame_writer_refuses_a_format_its_file_contradicts(tmp_path: Path) -> None:
    sim = hooke.Simulation.from_scene(ROOT / "scenes" / "cloth-pinned.toml")
    with pytest.raises(hooke.InputError, match=r"is a \.usda file but format is 'obj'"):
        hooke.FrameWriter(sim, tmp_path / "a.usda", format="obj")
    with pytest.raises(hooke.InputError, match="expected one of ply, obj, pc2, usda"):
        hooke.FrameWriter(sim, tmp_path, format="fbx")  # type: ignore[arg-type]


def test_ply_texture_coordinates_reach_the_obj_frames(tmp_path: Path) -> None:
    """A PLY mesh with `s t` per vertex: trimesh reads the same UVs from the OBJ frames."""
    n = 5
    u, v = np.meshgrid(np.linspace(0.0, 1.0, n), np.linspace(0.0, 1.0, n))
    positions = np.stack([u.ravel(), np.zeros(n * n), v.ravel()], axis=1)
    uvs = np.stack([0.2 + 0.5 * u.ravel(), 1.0 - v.ravel()], axis=1)
    faces = grid_triangles(n)
    header = (
        f"ply\nformat ascii 1.0\nelement vertex {n * n}\nproperty float x\nproperty float y\n"
        f"property float z\nproperty float s\nproperty float t\nelement face {len(faces)}\n"
        "property list uchar int vertex_indices\nend_header\n"
    )
    rows = [f"{x} {y} {z} {s} {t}" for (x, y, z), (s, t) in zip(positions, uvs, strict=True)]
    rows += [f"3 {a} {b} {c}" for a, b, c in faces]
    (tmp_path / "sheet.ply").write_text(header + "\n".join(rows) + "\n")
    scene = tmp_path / "scene.toml"
    scene.write_text(
        '[mesh]\ngenerator = "file"\npath = "sheet.ply"\n'
        "[material]\nmass = { total = 0.05 }\nstiffness = 50.0\n"
        '[pins]\nselect = ["corners"]\n[simulation]\ndt = "auto"\nsteps = 20\nframe_every = 20\n'
    )
    run_cli("run", str(scene), "--output", str(tmp_path / "obj"), "--output-format", "obj")
    mesh = trimesh.load_mesh(tmp_path / "obj" / "frame-0000020.obj", process=False)
    assert len(mesh.vertices) == n * n, "one UV per vertex: no vertex split"
    assert isinstance(mesh.visual, trimesh.visual.TextureVisuals)
    read = np.asarray(mesh.visual.uv, dtype=np.float64)
    np.testing.assert_allclose(read, uvs, atol=1e-7)
