"""`hooke run --output-format usda`, opened with Pixar's own USD library (usd-core): a sample of
the cloth's points for every frame, equal to the same run's PLY frames, the stage's metadata, the
colliders as animated prims, and nothing reported by USD's validators."""

import json
from pathlib import Path

import numpy as np
import pytest
from conftest import ROOT, run_cli
from pxr import Usd, UsdGeom, UsdValidation  # type: ignore[import-untyped]
from test_frame_formats import grid_triangles, ply_positions

import hooke

STEPS = 200
EVERY = 50
FRAMES = STEPS // EVERY + 1


def test_usd_stage_holds_every_frame_equal_to_the_ply_frames(tmp_path: Path) -> None:
    scene = ROOT / "scenes" / "wind-and-balls.toml"
    common = ["--steps", str(STEPS), "--frame-every", str(EVERY), "--backend", "cpu"]
    run_cli("run", str(scene), *common, "--output", str(tmp_path / "ply"))
    run_cli(
        "run", str(scene), *common, "--output", str(tmp_path / "usd"), "--output-format", "usda"
    )
    frames = [ply_positions(p) for p in sorted((tmp_path / "ply").glob("frame-*.ply"))]
    assert len(frames) == FRAMES
    path = tmp_path / "usd" / "frames.usda"

    stage = Usd.Stage.Open(str(path))
    assert UsdGeom.GetStageUpAxis(stage) == UsdGeom.Tokens.y
    assert UsdGeom.GetStageMetersPerUnit(stage) == 1.0
    assert stage.GetDefaultPrim().GetPath() == "/World"
    assert (stage.GetStartTimeCode(), stage.GetEndTimeCode()) == (0.0, FRAMES - 1.0)
    dt = json.loads((tmp_path / "usd" / "summary.json").read_text())["dt"]
    assert stage.GetTimeCodesPerSecond() == pytest.approx(1.0 / (EVERY * dt), rel=1e-12)
    assert stage.GetFramesPerSecond() == stage.GetTimeCodesPerSecond()

    mesh = UsdGeom.Mesh(stage.GetPrimAtPath("/World/cloth"))
    assert mesh.GetSubdivisionSchemeAttr().Get() == UsdGeom.Tokens.none
    assert mesh.GetDoubleSidedAttr().Get() is True
    counts = np.asarray(mesh.GetFaceVertexCountsAttr().Get())
    assert (counts == 3).all()
    times = mesh.GetPointsAttr().GetTimeSamples()
    assert times == [float(k) for k in range(FRAMES)]
    for time, expected in zip(times, frames, strict=True):
        points = np.asarray(mesh.GetPointsAttr().Get(time), dtype=np.float32)
        np.testing.assert_array_equal(points, expected)
        extent = np.asarray(mesh.GetExtentAttr().Get(time))
        np.testing.assert_array_equal(extent, [expected.min(0), expected.max(0)])

    balls = [p for p in stage.Traverse() if p.IsA(UsdGeom.Sphere)]
    assert len(balls) == 3
    for ball in balls:
        translate = ball.GetAttribute("xformOp:translate")
        assert translate.GetNumTimeSamples() == FRAMES, "the dynamic balls move"
    assert any(p.IsA(UsdGeom.Plane) for p in stage.Traverse()), "the ground plane"

    # Every validator USD registers (stage metadata, attribute types, composition, geometry
    # encapsulation, ...): none reports anything.
    validators = UsdValidation.ValidationRegistry().GetOrLoadAllValidators()
    assert len(validators) > 10
    reports = UsdValidation.ValidationContext(validators).Validate(stage)
    assert [f"{r.GetName()}: {r.GetMessage()}" for r in reports] == []


def validation_reports(stage: Usd.Stage) -> list[str]:
    validators = UsdValidation.ValidationRegistry().GetOrLoadAllValidators()
    reports = UsdValidation.ValidationContext(validators).Validate(stage)
    return [f"{r.GetName()}: {r.GetMessage()}" for r in reports]


def test_uvs_with_a_seam_go_into_usd_and_obj_per_corner(tmp_path: Path) -> None:
    """An OBJ whose every triangle corner has its own `vt` (seams everywhere): USD's `st`
    primvar is face-varying and, flattened, gives each corner its UV; the OBJ frames too."""
    n = 4
    u, v = np.meshgrid(np.linspace(0.0, 1.0, n), np.linspace(0.0, 1.0, n))
    positions = np.stack([u.ravel(), np.ones(n * n), v.ravel()], axis=1)
    triangles = grid_triangles(n)
    # Corner j of triangle k: the vertex's (x, z) shifted by k, so no two corners share a UV.
    corner_uvs = (
        positions[triangles][:, :, [0, 2]] + 0.01 * np.arange(len(triangles))[:, None, None]
    )
    lines = [f"v {x} {y} {z}" for x, y, z in positions]
    lines += [f"vt {s} {t}" for s, t in corner_uvs.reshape(-1, 2)]
    lines += [
        "f " + " ".join(f"{a + 1}/{3 * k + j + 1}" for j, a in enumerate(tri))
        for k, tri in enumerate(triangles)
    ]
    (tmp_path / "sheet.obj").write_text("\n".join(lines) + "\n")
    scene = tmp_path / "scene.toml"
    scene.write_text(
        '[mesh]\ngenerator = "file"\npath = "sheet.obj"\n'
        "[material]\nmass = { total = 0.05 }\nstiffness = 50.0\n"
        '[pins]\nselect = ["corners"]\n[simulation]\ndt = "auto"\nsteps = 20\nframe_every = 10\n'
    )

    run_cli("run", str(scene), "--output", str(tmp_path / "cloth.usda"))
    names = sorted(p.name for p in tmp_path.iterdir() if p.name.startswith("cloth"))
    assert names == [
        "cloth.final-state.ply",
        "cloth.final-state.toml",
        "cloth.summary.json",
        "cloth.usda",
    ]
    stage = Usd.Stage.Open(str(tmp_path / "cloth.usda"))
    mesh = stage.GetPrimAtPath("/World/cloth")
    st = UsdGeom.PrimvarsAPI(mesh).GetPrimvar("st")
    assert st.GetInterpolation() == UsdGeom.Tokens.faceVarying
    assert st.GetTypeName() == "texCoord2f[]"
    flat = np.asarray(st.ComputeFlattened(), dtype=np.float32)
    np.testing.assert_array_equal(flat, corner_uvs.reshape(-1, 2).astype(np.float32))
    assert validation_reports(stage) == []

    run_cli("run", str(scene), "--output", str(tmp_path / "obj"), "--output-format", "obj")
    text = (tmp_path / "obj" / "frame-0000020.obj").read_text().splitlines()
    vts = np.array([line.split()[1:] for line in text if line[:3] == "vt "], dtype=np.float32)
    corners = [
        [int(c.split("/")[1]) - 1 for c in line.split()[1:]] for line in text if line[:2] == "f "
    ]
    np.testing.assert_array_equal(vts[corners], corner_uvs.astype(np.float32))


def test_generated_sheets_and_python_arrays_carry_uvs_per_vertex(tmp_path: Path) -> None:
    run_cli(
        "run",
        str(ROOT / "scenes" / "cloth-pinned.toml"),
        "--steps",
        "10",
        "--output",
        str(tmp_path / "grid.usda"),
    )
    stage = Usd.Stage.Open(str(tmp_path / "grid.usda"))
    st = UsdGeom.PrimvarsAPI(stage.GetPrimAtPath("/World/cloth")).GetPrimvar("st")
    assert st.GetInterpolation() == UsdGeom.Tokens.vertex
    values = np.asarray(st.Get())
    assert values.shape == (64 * 64, 2)
    np.testing.assert_allclose(values.min(0), [0.0, 0.0])
    np.testing.assert_allclose(values.max(0), [1.0, 1.0])
    assert validation_reports(stage) == []

    vertices = np.array([[0.0, 0.0, 0.0], [1.0, 0.0, 0.0], [1.0, 0.0, 1.0], [0.0, 0.0, 1.0]])
    uvs = np.array([[0.0, 0.0], [1.0, 0.0], [1.0, 1.0], [0.0, 1.0]])
    sim = hooke.Simulation.from_arrays(
        vertices, [[0, 1, 2], [0, 2, 3]], stiffness=10.0, mass_total=0.1, pins=[0], uvs=uvs
    )
    with hooke.FrameWriter(sim, tmp_path / "arrays.usda") as frames:
        frames.write()
        sim.step(5)
        frames.write()
    stage = Usd.Stage.Open(str(tmp_path / "arrays.usda"))
    mesh = UsdGeom.Mesh(stage.GetPrimAtPath("/World/cloth"))
    assert mesh.GetPointsAttr().GetTimeSamples() == [0.0, 5.0]
    st = UsdGeom.PrimvarsAPI(mesh).GetPrimvar("st")
    np.testing.assert_array_equal(np.asarray(st.Get()), uvs.astype(np.float32))
    np.testing.assert_array_equal(np.asarray(mesh.GetPointsAttr().Get(5.0)), sim.positions())
    with pytest.raises(hooke.InputError, match=r"uvs must have one row per vertex \(4\)"):
        hooke.Simulation.from_arrays(
            vertices, [[0, 1, 2]], stiffness=1.0, mass_total=1.0, uvs=uvs[:3]
        )
