"""The Python package against the CLI, against physics, and against bad input."""

import json
import threading
import tracemalloc
from pathlib import Path
from typing import Any, Literal

import numpy as np
import numpy.typing as npt
import pytest
from conftest import SCENES, run_cli

import hooke

G = 9.81


def sheet(n: int = 8) -> tuple[npt.NDArray[np.float64], npt.NDArray[np.int64]]:
    """An n x n grid in the x-z plane at height 1 m, 1 m wide: vertices and triangles."""
    xs = np.linspace(0.0, 1.0, n)
    vertices = np.array([[x, 1.0, z] for z in xs for x in xs])
    triangles = []
    for r in range(n - 1):
        for c in range(n - 1):
            a, b, d = r * n + c, r * n + c + 1, (r + 1) * n + c
            triangles += [[a, d, b], [b, d, d + 1]]
    return vertices, np.array(triangles)


# ---- the same results as the CLI ------------------------------------------------------------


@pytest.mark.parametrize("method", ["gather", "scatter"])
def test_python_and_cli_write_byte_identical_states_and_frames(
    tmp_path: Path, method: Literal["gather", "scatter"]
) -> None:
    scene = SCENES / "wind-and-balls.toml"  # dynamic balls, wind, applied forces
    out = tmp_path / "cli"
    run_cli(
        "run",
        str(scene),
        "--steps",
        "100",
        "--frame-every",
        "100",
        "--method",
        method,
        "--output",
        str(out),
    )
    sim = hooke.Simulation.from_scene(scene, backend="cpu", method=method)
    sim.step(100)
    sim.save_state(tmp_path / "py.ply")
    sim.write_frame(tmp_path / "frame.ply")
    assert (tmp_path / "py.ply").read_bytes() == (out / "final-state.ply").read_bytes()
    assert (tmp_path / "py.toml").read_bytes() == (out / "final-state.toml").read_bytes()
    assert (tmp_path / "frame.ply").read_bytes() == (out / "frame-0000100.ply").read_bytes()


def test_a_python_state_resumes_on_the_cli_and_back(tmp_path: Path) -> None:
    scene = SCENES / "ball-through-curtain.toml"  # keyframed colliders
    whole = hooke.Simulation.from_scene(scene)
    whole.step(200)
    half = hooke.Simulation.from_scene(scene)
    half.step(100)
    half.save_state(tmp_path / "half.ply")
    run_cli(
        "run",
        str(scene),
        "--steps",
        "100",
        "--no-frames",
        "--resume",
        str(tmp_path / "half.ply"),
        "--output",
        str(tmp_path / "cli"),
    )
    resumed = hooke.Simulation.from_scene(scene)
    resumed.load_state(tmp_path / "cli" / "final-state.ply")
    assert resumed.steps_taken == 200
    np.testing.assert_array_equal(resumed.positions(), whole.positions())


# ---- physics reached from Python -----------------------------------------------------------


@pytest.mark.parametrize("backend", ["reference", "cpu"])
def test_free_fall_follows_verlet_in_closed_form(backend: Literal["reference", "cpu"]) -> None:
    vertices, triangles = sheet(4)
    sim = hooke.Simulation.from_arrays(
        vertices, triangles, stiffness=10.0, mass_total=0.1, dt=1e-3, backend=backend
    )
    n = 300
    sim.step(n)
    # Delta-form Verlet from rest: the drop after n steps is g dt^2 n (n + 1) / 2.
    expected = 1.0 - G * 1e-3**2 * n * (n + 1) / 2
    # positions() are float32: the reference is exact to their rounding (6e-8), the float32
    # solver to its own accumulated rounding.
    tolerance = 1e-7 if backend == "reference" else 1e-6
    np.testing.assert_allclose(sim.positions()[:, 1], expected, rtol=tolerance)


def test_energy_is_conserved_without_damping_and_lost_with_it() -> None:
    vertices, triangles = sheet(10)

    def drift(damping: float) -> float:
        sim = hooke.Simulation.from_arrays(
            vertices,
            triangles,
            stiffness=200.0,
            mass_total=0.2,
            select=["corners"],
            damping=damping,
            backend="reference",
        )
        start = sim.energy()["total"]
        kinetic = 0.0
        for _ in range(40):
            sim.step(50)
            kinetic = max(kinetic, sim.energy()["kinetic"])
        return abs(sim.energy()["total"] - start) / kinetic

    # Verlet's energy error oscillates with the motion; measured 0.16% of the largest kinetic
    # energy undamped. Damping of 0.0005 kg/s loses 71%: the bars tell the two apart.
    assert drift(0.0) < 0.01
    assert drift(0.0005) > 0.1


def test_pin_reactions_balance_the_weight_of_a_hanging_cloth() -> None:
    vertices, triangles = sheet(8)
    sim = hooke.Simulation.from_arrays(
        vertices,
        triangles,
        stiffness=100.0,
        mass_total=0.2,
        select=["corners"],
        damping=0.05,
        backend="reference",
    )
    sim.step(20000)  # settles: heavy damping
    pins, forces = sim.pin_reactions()
    assert sorted(pins.tolist()) == sorted(sim.pins()) and len(pins) == 4
    weight = 0.2 * G
    # Settled in float64: measured 1.2e-13 of the weight off.
    np.testing.assert_allclose(forces.sum(axis=0), [0.0, weight, 0.0], atol=1e-6 * weight)


# float32 against float64 after 300 steps: the solvers score 1e-7 (rounding).
AGREEMENT = 1e-5


def test_solvers_agree_with_the_float64_reference(backend: Literal["cpu", "gpu"]) -> None:
    vertices, triangles = sheet(16)

    def run(
        backend: Literal["reference", "cpu", "gpu"],
        stiffness_scale: float = 1.0,
        damping: float = 0.01,
    ) -> npt.NDArray[np.float64]:
        sim = hooke.Simulation.from_arrays(
            vertices,
            triangles,
            stiffness=50.0,
            mass_total=0.2,
            select=["corners"],
            damping=0.01,
            backend=backend,
        )
        sim.set_material(stiffness_scale=stiffness_scale, damping=damping)
        sim.step(300)
        return sim.positions().astype(np.float64)

    expected = run("reference")

    def error(positions: npt.NDArray[np.float64]) -> float:
        return float(np.linalg.norm(positions - expected) / np.linalg.norm(expected))

    # The bar must reject broken solvers (measured: never moves 1.2e-1, springs off 2.3e-1,
    # stiffness 1% off 4.7e-4, damping ignored 1.1e-1), or passing it proves nothing.
    broken = {
        "never moves": error(vertices),
        "springs off": error(run("reference", stiffness_scale=1e-9)),
        "stiffness 1% off": error(run("reference", stiffness_scale=1.01)),
        "damping ignored": error(run("reference", damping=0.0)),
    }
    assert all(score > AGREEMENT for score in broken.values()), broken
    assert error(run(backend)) < AGREEMENT


def test_per_spring_stiffness_and_per_vertex_mass_arrays_are_used() -> None:
    vertices, triangles = sheet(8)
    springs = hooke.springs(triangles)

    def run(stiffness: object, mass: object) -> npt.NDArray[np.float32]:
        sim = hooke.Simulation.from_arrays(
            vertices,
            triangles,
            stiffness=stiffness,  # type: ignore[arg-type]
            mass_per_vertex=mass,  # type: ignore[arg-type]
            select=["corners"],
            dt=1e-3,
        )
        assert sim.spring_count == len(springs)
        sim.step(200)
        return sim.positions()

    uniform = run(50.0, 0.01)
    # Arrays of the same values give the same run, bit for bit.
    same = run(np.full(len(springs), 50.0), np.full(len(vertices), 0.01))
    np.testing.assert_array_equal(same, uniform)
    # A heavier vertex and softer springs change it.
    masses = np.full(len(vertices), 0.01)
    masses[27] = 0.05
    assert not np.array_equal(run(50.0, masses), uniform)
    stiffness = np.full(len(springs), 50.0)
    stiffness[::2] = 25.0
    assert not np.array_equal(run(stiffness, 0.01), uniform)


def test_bending_springs_join_the_far_corners_of_triangle_pairs() -> None:
    vertices, triangles = sheet(8)
    springs = hooke.springs(triangles)

    def build(**options: Any) -> hooke.Simulation:
        return hooke.Simulation.from_arrays(
            vertices,
            triangles,
            stiffness=np.full(len(springs), 50.0),
            mass_total=0.1,
            select=["corners"],
            **options,
        )

    bent = build(bending={"stiffness": 5.0})
    # One bending spring across each interior edge of the 8 x 8 grid, after the edge springs.
    interior = 7 * 6 * 2 + 7 * 7
    assert (bent.spring_count, bent.bending_spring_count) == (len(springs) + interior, interior)
    ends = bent.springs()
    np.testing.assert_array_equal(ends[: len(springs)], springs)
    mesh_edges = {tuple(e) for e in springs.tolist()}
    assert not any(tuple(e) in mesh_edges for e in ends[len(springs) :].tolist())
    assert build().bending_spring_count == 0
    with pytest.raises(hooke.InputError, match=r"bending\.stiffness: must be a positive number"):
        build(bending={"stiffness": -1.0})
    # Their own dampers count against the stable time step.
    damped = build(bending={"stiffness": 5.0, "damping": 0.01})
    assert damped.stable_dt()[0] < bent.stable_dt()[0]
    with pytest.raises(hooke.InputError, match=r"bending\.damping: must be zero or positive"):
        build(bending={"stiffness": 5.0, "damping": -1.0})


def test_a_vertex_pinned_while_running_stays_there_until_unpinned() -> None:
    vertices, triangles = sheet(8)
    sim = hooke.Simulation.from_arrays(
        vertices, triangles, stiffness=50.0, mass_total=0.1, select=["corners"], dt=1e-3
    )
    sim.step(100)
    middle = 27
    sim.pin(middle, at=(0.45, 1.2, 0.45))
    assert middle in sim.pins() and sim.steps_taken == 100
    sim.step(300)
    np.testing.assert_allclose(sim.positions()[middle], (0.45, 1.2, 0.45), atol=1e-6)
    sim.unpin(middle)
    sim.step(300)
    assert sim.positions()[middle][1] < 1.15
    with pytest.raises(hooke.InputError, match="pinned vertex 64 does not exist"):
        sim.pin(64)


def test_handles_carry_their_vertices_along_their_paths() -> None:
    vertices, triangles = sheet(8)
    sim = hooke.Simulation.from_arrays(
        vertices,
        triangles,
        stiffness=50.0,
        mass_total=0.1,
        dt=1e-3,
        handles=[
            {"vertices": [0, 7], "path": [[0, 0, 0, 0], [0.2, 0, 0.3, 0]]},
            {"vertices": [56, 63], "path": [[0, 0, 0, 0], [0.2, 0, 0.3, 0]], "repeat": True},
        ],
    )
    assert {0, 7, 56, 63} <= set(sim.pins())
    sim.step(100)  # t = 0.1 s: halfway along both paths
    np.testing.assert_allclose(
        sim.positions()[[0, 7, 56, 63]], vertices[[0, 7, 56, 63]] + (0, 0.15, 0), atol=1e-6
    )
    sim.step(150)  # t = 0.25 s: the first handle holds at its end, the second started over
    np.testing.assert_allclose(sim.positions()[0], vertices[0] + (0, 0.3, 0), atol=1e-6)
    np.testing.assert_allclose(sim.positions()[56], vertices[56] + (0, 0.075, 0), atol=1e-6)
    with pytest.raises(hooke.InputError, match=r"handle\[0\]\.collider: collider 2 does not exist"):
        hooke.Simulation.from_arrays(
            vertices,
            triangles,
            stiffness=50.0,
            mass_total=0.1,
            handles=[{"vertices": [0], "collider": 2}],
        )


def test_tearing_breaks_springs_for_good_as_the_cli_does(tmp_path: Path) -> None:
    scene = SCENES / "tearing.toml"
    sim = hooke.Simulation.from_scene(scene)
    sim.step(1430)  # the tear has begun
    saved = sim.snapshot()
    sim.step(570)
    broken = sim.broken_springs()
    assert 0 < saved.broken_spring_count < len(broken)
    assert np.all(np.diff(broken) > 0) and broken[-1] < sim.spring_count
    out = tmp_path / "cli"
    run_cli("run", str(scene), "--steps", "2000", "--no-frames", "--output", str(out))
    summary = json.loads((out / "summary.json").read_text())
    assert summary["broken_springs"] == len(broken)
    # Torn springs pull on nothing: once the halves have parted, every spring still whole is
    # back under the 1.3 limit.
    assert sim.max_strain()[0] < 0.3
    # A snapshot keeps the tears it was taken with.
    sim.restore(saved)
    assert len(sim.broken_springs()) == saved.broken_spring_count
    vertices, triangles = sheet(8)
    with pytest.raises(hooke.InputError, match=r"tearing\.max_stretch: must be a number above 1"):
        hooke.Simulation.from_arrays(
            vertices, triangles, stiffness=50.0, mass_total=0.1, tearing={"max_stretch": 0.9}
        )


# ---- live control ---------------------------------------------------------------------------


def test_live_material_edits_equal_a_simulation_built_with_them() -> None:
    scene = SCENES / "cloth-pinned.toml"
    live = hooke.Simulation.from_scene(scene)
    live.step(50)
    saved = live.snapshot()
    live.set_material(damping=0.002, stiffness_scale=0.5, gravity=(0.0, -5.0, 1.0))
    live.set_wind((1.0, 0.0, 2.0), 0.3)
    live.step(100)
    rebuilt = hooke.Simulation.from_scene(scene)
    rebuilt.set_material(damping=0.002, stiffness_scale=0.5, gravity=(0.0, -5.0, 1.0))
    rebuilt.set_wind((1.0, 0.0, 2.0), 0.3)
    rebuilt.restore(saved)
    rebuilt.step(100)
    np.testing.assert_array_equal(live.positions(), rebuilt.positions())
    untouched = hooke.Simulation.from_scene(scene)
    untouched.step(150)
    assert not np.array_equal(untouched.positions(), live.positions())


def test_a_drag_pulls_its_vertex_to_the_target() -> None:
    sim = hooke.Simulation.from_scene(SCENES / "cloth-pinned.toml")
    target = (0.0, 1.5, 0.0)
    middle = sim.vertex_count // 2 + 32
    start = np.linalg.norm(sim.positions()[middle] - target)
    sim.set_drags([(middle, target, 50.0)])
    sim.step(3000)
    assert np.linalg.norm(sim.positions()[middle] - target) < 0.5 * start
    sim.set_drags([])
    sim.set_point_forces([(middle, (0.0, 0.1, 0.0))])


def test_snapshot_and_restore_continue_bit_for_bit() -> None:
    scene = SCENES / "wind-and-balls.toml"
    whole = hooke.Simulation.from_scene(scene)
    whole.step(200)
    sim = hooke.Simulation.from_scene(scene)
    sim.step(100)
    saved = sim.snapshot()
    sim.step(37)
    sim.restore(saved)
    assert sim.steps_taken == 100
    sim.step(100)
    np.testing.assert_array_equal(sim.positions(), whole.positions())


def test_colliders_and_self_collision_from_dicts() -> None:
    vertices, triangles = sheet(12)
    ball = {"kind": "sphere", "center": [0.5, 0.6, 0.5], "radius": 0.2, "friction": 0.3}
    ground = {"kind": "plane", "point": [0, 0, 0], "normal": [0, 1, 0]}
    sim = hooke.Simulation.from_arrays(
        vertices,
        triangles,
        stiffness=100.0,
        mass_total=0.1,
        damping=0.001,
        thickness=0.005,
        colliders=[ball, ground],
        self_collision={"distance": 0.02, "grids": 2},
    )
    sim.step(4000)
    p = sim.positions().astype(np.float64)
    clearance = np.linalg.norm(p - [0.5, 0.6, 0.5], axis=1) - 0.2
    assert clearance.min() > 0.0 and p[:, 1].min() > 0.0
    assert [c["kind"] for c in sim.colliders()] == ["sphere", "plane"]
    timed = sim.step_timed()
    parts = timed["self_collision"]
    assert parts is not None and 0 < parts["total"] <= timed["collision"], timed
    assert parts["measuring"] + parts["sorting"] + parts["window_tests"] > 0, parts
    sim.set_self_collision(None)
    sim.step(10)


def test_balls_take_forces() -> None:
    sim = hooke.Simulation.from_scene(SCENES / "wind-and-balls.toml")
    dynamic = [i for i, c in enumerate(sim.colliders()) if c["dynamic"]]
    sim.set_ball_forces([(dynamic[0], (0.0, 2.0, 0.0))])
    sim.step(10)
    with pytest.raises(hooke.InputError, match="not a dynamic ball"):
        sim.set_ball_forces([(99, (0.0, 1.0, 0.0))])


# ---- reports --------------------------------------------------------------------------------


def test_reports_match_the_cli_scene_facts() -> None:
    sim = hooke.Simulation.from_scene(SCENES / "cloth-pinned.toml")
    assert (sim.vertex_count, sim.spring_count) == (4096, 12033)
    dt, vertex = sim.stable_dt()
    assert sim.dt == pytest.approx(0.9 * dt) and vertex is not None
    assert sim.memory()["total"] > 0
    timed = sim.step_timed()
    assert timed["total"] > 0 and timed["source"] == "wall-clock"
    assert timed["self_collision"] is None
    strain, spring = sim.max_strain()
    assert 0 <= spring < sim.spring_count and strain >= 0
    assert sim.springs().shape == (12033, 2)
    np.testing.assert_array_equal(hooke.springs(sim.triangles()), sim.springs())


def test_steps_timed_time_every_step_and_step_as_step_does(backend: Literal["cpu", "gpu"]) -> None:
    timed = hooke.Simulation.from_scene(SCENES / "cloth-pinned.toml", backend=backend)
    plain = hooke.Simulation.from_scene(SCENES / "cloth-pinned.toml", backend=backend)
    # 13 steps: on a GPU, a submission of 10 timed steps and one of 3.
    steps = timed.steps_timed(13)
    plain.step(13)
    assert len(steps) == 13 and timed.steps_taken == 13
    assert all(step["force_calculation"] > 0 for step in steps), steps
    (source,) = {step["source"] for step in steps}
    assert backend == "gpu" or source == "wall-clock", source
    np.testing.assert_array_equal(timed.positions(), plain.positions())


def test_render_draws_the_cloth(tmp_path: Path, gpu: None) -> None:
    sim = hooke.Simulation.from_scene(SCENES / "cloth-pinned.toml")
    sim.step(200)
    image = sim.render(160, 90)
    assert image.shape == (90, 160, 4) and image.dtype == np.uint8
    pixels = image.astype(np.int32)
    salmon = (pixels[..., 0] - pixels[..., 1]) > 40  # the cloth's checker; the ground is grey
    assert salmon.sum() > 500, salmon.sum()
    sim.save_png(tmp_path / "cloth.png", 160, 90)
    assert (tmp_path / "cloth.png").read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"


# ---- errors ---------------------------------------------------------------------------------


def test_bad_input_raises_hookes_exceptions_with_the_librarys_message(tmp_path: Path) -> None:
    vertices, triangles = sheet(3)
    bad_scene = tmp_path / "bad.toml"
    bad_scene.write_text('[mesh]\ngenerator = "grid"\nresolution = [4, 4]\nsizes = 3\n')
    with pytest.raises(hooke.InputError, match=r"(?s)bad\.toml.*line 4.*sizes"):
        hooke.Simulation.from_scene(bad_scene)
    with pytest.raises(hooke.InputError, match="nope.toml"):
        hooke.Simulation.from_scene(tmp_path / "nope.toml")
    with pytest.raises(hooke.InputError, match=r"shape \(N, 3\)"):
        hooke.Simulation.from_arrays(vertices[:, :2], triangles, stiffness=1.0, mass_total=1.0)
    with pytest.raises(hooke.InputError, match="integer"):
        hooke.Simulation.from_arrays(vertices, triangles * 1.0, stiffness=1.0, mass_total=1.0)
    with pytest.raises(hooke.InputError, match="pins.vertices: vertex 99 does not exist"):
        hooke.Simulation.from_arrays(vertices, triangles, stiffness=1.0, mass_total=1.0, pins=[99])
    with pytest.raises(hooke.InputError, match="material.mass"):
        hooke.Simulation.from_arrays(vertices, triangles, stiffness=1.0)
    with pytest.raises(hooke.InputError, match="stiffness must be a number or an array"):
        hooke.Simulation.from_arrays(vertices, triangles, stiffness=[1.0, 2.0], mass_total=1.0)
    with pytest.raises(hooke.InputError, match="unknown backend"):
        hooke.Simulation.from_arrays(
            vertices,
            triangles,
            stiffness=1.0,
            mass_total=1.0,
            backend="tpu",  # type: ignore[arg-type]
        )
    sim = hooke.Simulation.from_arrays(vertices, triangles, stiffness=1.0, mass_total=1.0)
    with pytest.raises(hooke.InputError, match="9 rows"):
        sim.set_positions(np.zeros((4, 3)))
    with pytest.raises(hooke.InputError, match="above the stability bound"):
        sim.set_material(dt=10.0)
    with pytest.raises(hooke.InputError, match="vertex 50"):
        sim.set_drags([(50, (0, 0, 0), 1.0)])
    assert issubclass(hooke.SimulationError, hooke.HookeError)


def test_a_blow_up_raises_simulation_error() -> None:
    vertices, triangles = sheet(4)
    sim = hooke.Simulation.from_arrays(
        vertices, triangles, stiffness=1000.0, mass_total=0.01, dt=0.05, allow_unstable=True
    )
    with pytest.raises(hooke.SimulationError, match="step"):
        sim.step(100000)


# ---- the GIL and copies ---------------------------------------------------------------------


def test_step_releases_the_gil() -> None:
    sim = hooke.Simulation.from_scene(SCENES / "cloth-pinned.toml", backend="reference")
    counts = 0
    running = True

    def count() -> None:
        nonlocal counts
        while running:
            counts += 1

    thread = threading.Thread(target=count)
    thread.start()
    before = counts
    sim.step(300)  # ~0.3 s of float64 stepping
    during = counts - before
    running = False
    thread.join()
    # With the GIL held the counter could not move until step returned.
    assert during > 10_000, during


def test_positions_and_set_positions_make_no_copies_of_their_own() -> None:
    sim = hooke.Simulation.from_scene(SCENES / "cloth-pinned.toml")
    one_copy = sim.vertex_count * 3 * 4
    tracemalloc.start()
    positions = sim.positions()
    _, peak_out = tracemalloc.get_traced_memory()
    tracemalloc.stop()
    # The array wraps the vector Rust filled: numpy allocates no data buffer of its own.
    assert peak_out < one_copy / 4, peak_out
    mine = np.ascontiguousarray(positions, dtype=np.float64)
    tracemalloc.start()
    sim.set_positions(mine)
    _, peak_in = tracemalloc.get_traced_memory()
    tracemalloc.stop()
    # A contiguous float64 array is read in place.
    assert peak_in < one_copy / 4, peak_in
