"""`hooke run --output-format usda`, opened with Pixar's own USD library (usd-core): a sample of
the cloth's points for every frame, equal to the same run's PLY frames, the stage's metadata, the
colliders as animated prims, and nothing reported by USD's validators."""

import json
from pathlib import Path

import numpy as np
import pytest
from conftest import ROOT, run_cli
from pxr import Usd, UsdGeom, UsdValidation  # type: ignore[import-untyped]
from test_frame_formats import ply_positions

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
