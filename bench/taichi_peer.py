"""The Taichi peer of `hooke bench --backend gpu`: the same workload in Taichi on its Vulkan
backend, for a side-by-side comparison on the same driver (issue 14: every hooke GPU method at
least 1.5x faster than Taichi's same method).

The workload is `hooke bench`'s: an n x n grid over the unit square in the x-z plane, every
unique edge of its triangles (two per cell, split along the v00-v11 diagonal) a spring with
stiffness 0.25 m / dt^2, mass 1 / N per vertex, damping 0.01 m / dt, dt = 1 ms, gravity, the
four corners pinned; damped Verlet in delta form, as hooke integrates.

Methods, each written the way a Taichi user would:
- gather: one kernel per step; each vertex sums its springs from a CSR adjacency (in the mesh's
  vertex order) and integrates.
- scatter: one kernel adds every spring's force to both ends with atomic adds, a second
  integrates (and clears the forces).

Run it with `./run peer-taichi` (which installs Taichi into .venv-taichi), or directly:
`python bench/taichi_peer.py --sizes 128,256,512 --steps 300`. It prints a Markdown table of
ms/step: the median over `--repeats` timed blocks of `--steps` steps, each block ending in
`ti.sync()`, after a warm-up block that includes compilation.
"""
# No `from __future__ import annotations`: Taichi reads its kernels' annotations as objects.
# Those annotations (`ti.template()`) are Taichi's DSL, not Python types; mypy checks the rest.
# mypy: disable-error-code="valid-type,untyped-decorator,no-untyped-def"

import argparse
import statistics
import time

import numpy as np
import taichi as ti

DT = 1e-3
GRAVITY = (0.0, -9.81, 0.0)


def grid_springs(n: int) -> np.ndarray:
    """Unique edges of hooke's grid triangulation, as (a, b) rows with a < b."""
    v = np.arange(n * n, dtype=np.int64).reshape(n, n)
    v00, v01 = v[:-1, :-1].ravel(), v[:-1, 1:].ravel()
    v10, v11 = v[1:, :-1].ravel(), v[1:, 1:].ravel()
    # Triangles (v00, v10, v11) and (v00, v11, v01): their edges, deduplicated.
    edges = np.concatenate(
        [
            np.stack([v00, v10], 1),
            np.stack([v10, v11], 1),
            np.stack([v00, v11], 1),
            np.stack([v11, v01], 1),
            np.stack([v00, v01], 1),
        ]
    )
    edges.sort(axis=1)
    return np.unique(edges, axis=0).astype(np.int32)


def grid_positions(n: int) -> np.ndarray:
    u = np.linspace(-0.5, 0.5, n)
    x, z = np.meshgrid(u, u)  # rows run along z, columns along x, as hooke numbers them
    return np.stack([x.ravel(), np.zeros(n * n), z.ravel()], 1).astype(np.float32)


class Sheet:
    """Fields shared by both methods."""

    def __init__(self, n: int) -> None:
        count = n * n
        positions = grid_positions(n)
        springs = grid_springs(n)
        mass = 1.0 / count
        self.count, self.spring_count = count, len(springs)
        self.stiffness = 0.25 * mass / (DT * DT)
        damping = 0.01 * mass / DT
        rest = np.linalg.norm(positions[springs[:, 0]] - positions[springs[:, 1]], axis=1)
        free = np.ones(count, dtype=np.float32)
        free[[0, n - 1, count - n, count - 1]] = 0.0
        self.x = ti.Vector.field(3, ti.f32, count)
        self.x_next = ti.Vector.field(3, ti.f32, count)
        self.d = ti.Vector.field(3, ti.f32, count)
        # Per vertex: dt^2 / m and 1 - c dt / m, both 0 when pinned.
        self.scale = ti.Vector.field(2, ti.f32, count)
        self.x.from_numpy(positions)
        self.d.fill(0.0)
        scales = np.stack([free * DT * DT / mass, free * (1.0 - damping * DT / mass)], 1)
        self.scale.from_numpy(scales.astype(np.float32))
        self.springs_np, self.rest_np = springs, rest.astype(np.float32)


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
        a, b = self.springs_np[:, 0], self.springs_np[:, 1]
        ends = np.concatenate([a, b])
        others = np.concatenate([b, a])
        rests = np.concatenate([self.rest_np, self.rest_np])
        order = np.argsort(ends, kind="stable")
        offsets = np.zeros(self.count + 1, dtype=np.int32)
        np.cumsum(np.bincount(ends, minlength=self.count), out=offsets[1:])
        self.offsets = ti.field(ti.i32, self.count + 1)
        self.neighbors = ti.field(ti.i32, len(ends))
        self.rests = ti.field(ti.f32, len(ends))
        self.offsets.from_numpy(offsets)
        self.neighbors.from_numpy(others[order].astype(np.int32))
        self.rests.from_numpy(rests[order])

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
        self.ends.from_numpy(self.springs_np)
        self.rests.from_numpy(self.rest_np)
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
    args = parser.parse_args()
    ti.init(arch=getattr(ti, args.arch), default_fp=ti.f32, offline_cache=True)
    print(f"taichi {ti.__version__} on {args.arch}; median ms/step of {args.repeats} blocks")
    print("| mesh | method | springs | ms/step (median) | range | dispatches |")
    print("|---|---|---|---|---|---|")
    for n in (int(s) for s in args.sizes.split(",")):
        for method in args.methods.split(","):
            sheet: Gather | Scatter = Gather(n) if method == "gather" else Scatter(n)
            times = time_method(sheet, args.steps, args.repeats)
            x = sheet.x.to_numpy()
            if not np.isfinite(x).all():
                raise SystemExit(f"{method} at {n}^2 went non-finite")
            print(
                f"| grid {n}^2 | {method} | {sheet.spring_count} | {statistics.median(times):.3f}"
                f" | {min(times):.3f}-{max(times):.3f} | {sheet.dispatches()} |",
                flush=True,
            )


if __name__ == "__main__":
    main()
