"""The NVIDIA Warp peer of `hooke bench --backend gpu`: the same workload in Warp (CUDA), for a
side-by-side comparison on one GPU (issue 14's real-GPU figures).

The workload is `hooke bench`'s (bench/workload.py): grids of n x n vertices, and optionally any
mesh hooke wrote as PLY (the bench's irregular mesh: see workload.py). Methods, each written the
way a Warp user would:
- gather: one kernel per step; each vertex sums its springs from a CSR adjacency (in the mesh's
  vertex order) and integrates.
- scatter: one kernel adds every spring's force to both ends with `wp.atomic_add`, a second
  integrates (and clears the forces).

Steps are replayed from a captured CUDA graph of two steps (Warp's way to run a simulation loop
without launch overhead; `--no-graph` launches each kernel). It prints a Markdown table of
ms/step: the median over `--repeats` timed blocks of `--steps` steps, each ending in
`wp.synchronize()`, after a warm-up block that includes compilation.

`--compare PLY --compare-steps N` first checks the workload itself: N gather steps of the grid
the PLY's mesh came from must match the state hooke wrote there (`hooke run
scenes/bench-grid-128.toml --steps N --backend gpu --no-frames --output DIR` writes one).

Warp is not in .venv; on a machine with a GPU and no network, carry its wheel (see the real-GPU
sections of docs/performance-log.md).
Run: `python bench/warp_peer.py --sizes 128,256,512 --steps 300`.
"""
# Warp reads its kernels' annotations (`wp.array(dtype=...)`) as objects: they are Warp's DSL,
# not Python types, so no `from __future__ import annotations`; mypy checks the rest.
# mypy: disable-error-code="valid-type,untyped-decorator,no-untyped-def,misc,no-any-return"

import argparse
import statistics
import sys
import time
from pathlib import Path

import numpy as np
import warp as wp

sys.path.insert(0, str(Path(__file__).parent))
import workload  # noqa: E402  (beside this script, not a package)

# The workload's gravity over one step, dt^2 g, as a constant the kernels compile in.
GRAVITY_STEP = wp.constant(wp.vec3(*workload.GRAVITY) * (workload.DT * workload.DT))


@wp.func
def spring_force(near: wp.vec3, far: wp.vec3, k: float, rest: float):
    d = far - near
    length = wp.sqrt(wp.max(wp.dot(d, d), 1.0e-38))
    return k * (1.0 - rest / length) * d


@wp.func
def integrate(
    x: wp.array(dtype=wp.vec3),
    x_next: wp.array(dtype=wp.vec3),
    d: wp.array(dtype=wp.vec3),
    scale: wp.array(dtype=wp.vec2),
    v: int,
    force: wp.vec3,
):
    s = scale[v]
    delta = d[v] * s[1] + force * s[0] + GRAVITY_STEP
    if s[0] <= 0.0:
        delta = wp.vec3(0.0, 0.0, 0.0)
    d[v] = delta
    x_next[v] = x[v] + delta


@wp.kernel
def gather_step(
    x: wp.array(dtype=wp.vec3),
    x_next: wp.array(dtype=wp.vec3),
    d: wp.array(dtype=wp.vec3),
    scale: wp.array(dtype=wp.vec2),
    offsets: wp.array(dtype=wp.int32),
    neighbors: wp.array(dtype=wp.int32),
    rests: wp.array(dtype=wp.float32),
    k: float,
):
    v = wp.tid()
    p = x[v]
    force = wp.vec3(0.0, 0.0, 0.0)
    for e in range(offsets[v], offsets[v + 1]):
        force += spring_force(p, x[neighbors[e]], k, rests[e])
    integrate(x, x_next, d, scale, v, force)


@wp.kernel
def scatter_forces(
    x: wp.array(dtype=wp.vec3),
    ends: wp.array(dtype=wp.vec2i),
    rests: wp.array(dtype=wp.float32),
    forces: wp.array(dtype=wp.vec3),
    k: float,
):
    s = wp.tid()
    a = ends[s][0]
    b = ends[s][1]
    f = spring_force(x[a], x[b], k, rests[s])
    wp.atomic_add(forces, a, f)
    wp.atomic_add(forces, b, -f)


@wp.kernel
def scatter_integrate(
    x: wp.array(dtype=wp.vec3),
    x_next: wp.array(dtype=wp.vec3),
    d: wp.array(dtype=wp.vec3),
    scale: wp.array(dtype=wp.vec2),
    forces: wp.array(dtype=wp.vec3),
):
    v = wp.tid()
    integrate(x, x_next, d, scale, v, forces[v])
    forces[v] = wp.vec3(0.0, 0.0, 0.0)


class Sheet:
    """Arrays shared by both methods; `step(parity)` launches one step."""

    launches = 0

    def __init__(self, mesh: workload.Workload, device: str) -> None:
        self.mesh, self.device = mesh, device
        self.x = wp.array(mesh.positions, dtype=wp.vec3, device=device)
        self.x_next = wp.zeros_like(self.x)
        self.d = wp.zeros_like(self.x)
        self.scale = wp.array(mesh.scale, dtype=wp.vec2, device=device)

    def buffers(self, parity: int) -> tuple[wp.array, wp.array]:
        return (self.x, self.x_next) if parity == 0 else (self.x_next, self.x)

    def step(self, parity: int) -> None:
        raise NotImplementedError


class Gather(Sheet):
    launches = 1

    def __init__(self, mesh: workload.Workload, device: str) -> None:
        super().__init__(mesh, device)
        offsets, neighbors, rests = mesh.csr()
        self.offsets = wp.array(offsets, dtype=wp.int32, device=device)
        self.neighbors = wp.array(neighbors, dtype=wp.int32, device=device)
        self.rests = wp.array(rests, dtype=wp.float32, device=device)

    def step(self, parity: int) -> None:
        x, x_next = self.buffers(parity)
        wp.launch(
            gather_step,
            dim=self.mesh.count,
            inputs=[
                x,
                x_next,
                self.d,
                self.scale,
                self.offsets,
                self.neighbors,
                self.rests,
                self.mesh.stiffness,
            ],
            device=self.device,
        )


class Scatter(Sheet):
    launches = 2

    def __init__(self, mesh: workload.Workload, device: str) -> None:
        super().__init__(mesh, device)
        self.ends = wp.array(mesh.springs, dtype=wp.vec2i, device=device)
        self.rests = wp.array(mesh.rest, dtype=wp.float32, device=device)
        self.forces = wp.zeros_like(self.x)

    def step(self, parity: int) -> None:
        x, x_next = self.buffers(parity)
        wp.launch(
            scatter_forces,
            dim=len(self.mesh.springs),
            inputs=[x, self.ends, self.rests, self.forces, self.mesh.stiffness],
            device=self.device,
        )
        wp.launch(
            scatter_integrate,
            dim=self.mesh.count,
            inputs=[x, x_next, self.d, self.scale, self.forces],
            device=self.device,
        )


def make(method: str, mesh: workload.Workload, device: str) -> Sheet:
    return Gather(mesh, device) if method == "gather" else Scatter(mesh, device)


def time_method(sheet: Sheet, steps: int, repeats: int, graph: bool) -> list[float]:
    """ms/step of each timed block (an even number of steps keeps the buffers' roles)."""
    steps += steps % 2
    if graph:
        with wp.ScopedCapture(device=sheet.device) as capture:
            sheet.step(0)
            sheet.step(1)

        def pair() -> None:
            wp.capture_launch(capture.graph)
    else:

        def pair() -> None:
            sheet.step(0)
            sheet.step(1)

    def block() -> float:
        wp.synchronize_device(sheet.device)
        start = time.perf_counter()
        for _ in range(steps // 2):
            pair()
        wp.synchronize_device(sheet.device)
        return (time.perf_counter() - start) * 1e3 / steps

    block()  # compilation and warm-up
    return [block() for _ in range(repeats)]


def compare(path: Path, steps: int, device: str) -> None:
    """N gather steps of the grid hooke's PLY holds, against the state hooke wrote there."""
    hooke_state, triangles = workload.read_ply(path)
    side = int(round(np.sqrt(len(hooke_state))))
    mesh = workload.grid(side)
    if len(triangles) != 2 * (side - 1) ** 2:
        raise SystemExit(f"{path}: not a grid of {side}^2 vertices")
    sheet = Gather(mesh, device)
    for i in range(steps):
        sheet.step(i % 2)
    ours = sheet.buffers(steps % 2)[0].numpy()
    moved = np.abs(hooke_state - mesh.positions).max()
    error = np.abs(ours - hooke_state).max()
    print(
        f"compare: {steps} gather steps of grid {side}^2 against {path}: max |warp - hooke| "
        f"{error:.3e} m, max displacement {moved:.3e} m (ratio {error / moved:.2e})"
    )
    if not error < 1e-3 * moved:
        raise SystemExit("compare: warp and hooke ran different workloads")


def main() -> None:
    parser = argparse.ArgumentParser(description=(__doc__ or "").splitlines()[0])
    parser.add_argument("--sizes", default="128,256,512", help="grid sides, comma-separated")
    parser.add_argument("--mesh", type=Path, action="append", default=[], help="a PLY from hooke")
    parser.add_argument("--methods", default="gather,scatter")
    parser.add_argument("--steps", type=int, default=300, help="steps per timed block")
    parser.add_argument("--repeats", type=int, default=5, help="timed blocks per method")
    parser.add_argument("--device", default="cuda:0")
    parser.add_argument("--no-graph", action="store_true", help="launch kernels one by one")
    parser.add_argument("--compare", type=Path, help="hooke's final-state.ply of a grid")
    parser.add_argument("--compare-steps", type=int, default=100)
    args = parser.parse_args()
    wp.config.quiet = True
    wp.init()
    graph = not args.no_graph and wp.get_device(args.device).is_cuda
    if args.compare:
        compare(args.compare, args.compare_steps, args.device)
    name = wp.get_device(args.device).name
    how = "graph replay" if graph else "kernel launches"
    print(f"warp {wp.__version__} on {args.device} ({name}), {how}; median ms/step of blocks")
    print("| mesh | method | springs | ms/step (median) | range | launches/step |")
    print("|---|---|---|---|---|---|")
    meshes = [workload.grid(int(s)) for s in args.sizes.split(",") if s]
    meshes += [workload.from_ply(path) for path in args.mesh]
    for mesh in meshes:
        for method in args.methods.split(","):
            sheet = make(method, mesh, args.device)
            times = time_method(sheet, args.steps, args.repeats, graph)
            finite = np.isfinite(sheet.x.numpy()).all()
            print(
                f"| {mesh.name} | {method} | {len(mesh.springs)} | {statistics.median(times):.4f}"
                f" | {min(times):.4f}-{max(times):.4f} | {sheet.launches} |"
                + ("" if finite else " (went non-finite)"),
                flush=True,
            )
            del sheet


if __name__ == "__main__":
    main()
