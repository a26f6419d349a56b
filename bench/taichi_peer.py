"""The Taichi peer of `hooke bench --backend gpu`: the same workload in Taichi on its Vulkan
backend, for a side-by-side comparison on the same driver (issue 14: every hooke GPU method at
least 1.5x faster than Taichi's same method).

The workload is `hooke bench`'s grids, built by bench/workload.py (shared with the Warp peer,
warp_peer.py): n x n vertices over the unit square, every unique edge a spring, the bench's
material, the four corners pinned; damped Verlet in delta form, as hooke integrates.

Methods, each written the way a Taichi user would:
- gather: one kernel per step; each vertex sums its springs from a CSR adjacency (in the mesh's
  vertex order) and integrates.
- scatter: one kernel adds every spring's force to both ends with atomic adds, a second
  integrates (and clears the forces).

Run it with `./run peer-taichi` (which installs Taichi into .venv-taichi), or directly:
`python bench/taichi_peer.py --sizes 128,256,512 --steps 300`. It prints a Markdown table of
ms/step (or, with `--format json`, the same as JSON, which bench/versus_taichi.py reads): the
median over `--repeats` timed blocks of `--steps` steps, each block ending in `ti.sync()`,
after a warm-up block that includes compilation.
"""
# No `from __future__ import annotations`: Taichi reads its kernels' annotations as objects.
# Those annotations (`ti.template()`) are Taichi's DSL, not Python types; mypy checks the rest.
# mypy: disable-error-code="valid-type,untyped-decorator,no-untyped-def"

import argparse
import json
import statistics
import sys
import time
from pathlib import Path

import numpy as np
import taichi as ti

sys.path.insert(0, str(Path(__file__).parent))
import workload  # noqa: E402  (beside this script, not a package)

DT = workload.DT
GRAVITY = workload.GRAVITY


class Sheet:
    """Fields shared by both methods."""

    def __init__(self, n: int) -> None:
        mesh = workload.grid(n)
        self.mesh = mesh
        self.count, self.spring_count = mesh.count, len(mesh.springs)
        self.stiffness = mesh.stiffness
        self.x = ti.Vector.field(3, ti.f32, mesh.count)
        self.x_next = ti.Vector.field(3, ti.f32, mesh.count)
        self.d = ti.Vector.field(3, ti.f32, mesh.count)
        # Per vertex: dt^2 / m and 1 - c dt / m, both 0 when pinned.
        self.scale = ti.Vector.field(2, ti.f32, mesh.count)
        self.x.from_numpy(mesh.positions)
        self.d.fill(0.0)
        self.scale.from_numpy(mesh.scale)


@ti.func
def spring_force(near: ti.template(), far: ti.template(), k: ti.f32, rest: ti.f32):
    d = far - near
    length = ti.sqrt(ti.max(d.dot(d), 1e-38))
    return k * (1.0 - rest / length) * d


@ti.func
def integrate(
    x: ti.template(), x_next: ti.template(), d: ti.template(), scale: ti.template(), v, force
):
    s = scale[v]
    g = ti.Vector(GRAVITY) * (DT * DT)
    delta = d[v] * s[1] + force * s[0] + g
    if s[0] <= 0.0:
        delta = ti.Vector([0.0, 0.0, 0.0])
    d[v] = delta
    x_next[v] = x[v] + delta


@ti.data_oriented
class Gather(Sheet):
    def __init__(self, n: int) -> None:
        super().__init__(n)
        offsets, neighbors, rests = self.mesh.csr()
        self.offsets = ti.field(ti.i32, self.count + 1)
        self.neighbors = ti.field(ti.i32, len(neighbors))
        self.rests = ti.field(ti.f32, len(rests))
        self.offsets.from_numpy(offsets)
        self.neighbors.from_numpy(neighbors)
        self.rests.from_numpy(rests)

    @ti.kernel
    def step_from(self, x: ti.template(), x_next: ti.template()):
        for v in range(self.count):
            force = ti.Vector([0.0, 0.0, 0.0])
            for e in range(self.offsets[v], self.offsets[v + 1]):
                force += spring_force(x[v], x[self.neighbors[e]], self.stiffness, self.rests[e])
            integrate(x, x_next, self.d, self.scale, v, force)

    def step(self, parity: int) -> None:
        if parity == 0:
            self.step_from(self.x, self.x_next)
        else:
            self.step_from(self.x_next, self.x)

    def dispatches(self) -> int:
        return 1


@ti.data_oriented
class Scatter(Sheet):
    def __init__(self, n: int) -> None:
        super().__init__(n)
        self.ends = ti.Vector.field(2, ti.i32, self.spring_count)
        self.rests = ti.field(ti.f32, self.spring_count)
        self.forces = ti.Vector.field(3, ti.f32, self.count)
        self.ends.from_numpy(self.mesh.springs)
        self.rests.from_numpy(self.mesh.rest)
        self.forces.fill(0.0)

    @ti.kernel
    def spring_forces(self, x: ti.template()):
        for s in range(self.spring_count):
            a, b = self.ends[s][0], self.ends[s][1]
            f = spring_force(x[a], x[b], self.stiffness, self.rests[s])
            ti.atomic_add(self.forces[a], f)
            ti.atomic_add(self.forces[b], -f)

    @ti.kernel
    def integrate_from(self, x: ti.template(), x_next: ti.template()):
        for v in range(self.count):
            integrate(x, x_next, self.d, self.scale, v, self.forces[v])
            self.forces[v] = ti.Vector([0.0, 0.0, 0.0])

    def step(self, parity: int) -> None:
        x, x_next = (self.x, self.x_next) if parity == 0 else (self.x_next, self.x)
        self.spring_forces(x)
        self.integrate_from(x, x_next)

    def dispatches(self) -> int:
        return 2


def time_method(sheet: Gather | Scatter, steps: int, repeats: int) -> list[float]:
    """ms/step of each timed block (an even number of steps keeps the buffers' roles)."""
    steps += steps % 2

    def block() -> float:
        start = time.perf_counter()
        for i in range(steps):
            sheet.step(i % 2)
        ti.sync()
        return (time.perf_counter() - start) * 1e3 / steps

    block()  # compilation and warm-up
    return [block() for _ in range(repeats)]


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--sizes", default="128,256,512", help="grid sides, comma-separated")
    parser.add_argument("--methods", default="gather,scatter")
    parser.add_argument("--steps", type=int, default=200, help="steps per timed block")
    parser.add_argument("--repeats", type=int, default=5, help="timed blocks per method")
    parser.add_argument("--arch", default="vulkan", choices=["vulkan", "cpu", "cuda"])
    parser.add_argument("--format", default="table", choices=["table", "json"])
    args = parser.parse_args()
    ti.init(arch=getattr(ti, args.arch), default_fp=ti.f32, offline_cache=True)
    # Taichi falls back to its CPU backend, with only a warning, when the one asked for is
    # missing (no Vulkan driver, say): timings taken then are not the GPU method's.
    running = ti.cfg.arch.name
    if args.arch != "cpu" and running != args.arch:
        raise SystemExit(
            f"taichi_peer.py: asked for --arch {args.arch}, but Taichi runs on {running}"
            " (is the driver installed? `./run peer-taichi` installs Mesa's Vulkan driver)"
        )
    table = args.format == "table"
    if table:
        print(f"taichi {ti.__version__} on {running}; median ms/step of {args.repeats} blocks")
        print("| mesh | method | springs | ms/step (median) | range | dispatches |")
        print("|---|---|---|---|---|---|")
    rows = []
    for n in (int(s) for s in args.sizes.split(",")):
        for method in args.methods.split(","):
            sheet: Gather | Scatter = Gather(n) if method == "gather" else Scatter(n)
            times = time_method(sheet, args.steps, args.repeats)
            x = sheet.x.to_numpy()
            if not np.isfinite(x).all():
                raise SystemExit(f"{method} at {n}^2 went non-finite")
            row = {
                "mesh": f"grid {n}^2",
                "method": method,
                "springs": sheet.spring_count,
                "ms_per_step": statistics.median(times),
                "blocks_ms": times,
                "dispatches": sheet.dispatches(),
            }
            rows.append(row)
            if table:
                print(
                    f"| {row['mesh']} | {method} | {sheet.spring_count} | {row['ms_per_step']:.3f}"
                    f" | {min(times):.3f}-{max(times):.3f} | {sheet.dispatches()} |",
                    flush=True,
                )
    if not table:
        report = {"taichi": ti.__version__, "arch": running, "rows": rows}
        print(json.dumps(report, indent=2))


if __name__ == "__main__":
    main()
