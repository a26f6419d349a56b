"""`hooke bench`'s workload, built the way the peers (taichi_peer.py, warp_peer.py) need it.

An n x n grid over the unit square in the x-z plane, every unique edge of its triangles (two per
cell, split along the v00-v11 diagonal) a spring; or any triangle mesh hooke wrote as binary PLY
(`hooke run scenes/bench-irregular.toml --steps 0 --allow-unstable --no-frames --output DIR`
writes the bench's irregular mesh to DIR/final-state.ply). Stiffness 0.25 m / dt^2, mass 1 / N
per vertex, damping 0.01 m / dt, dt = 1 ms, gravity, the four corners pinned; damped Verlet in
delta form, as hooke integrates.
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

import numpy as np
import numpy.typing as npt

DT = 1e-3
GRAVITY = (0.0, -9.81, 0.0)

Floats = npt.NDArray[np.float32]
Ints = npt.NDArray[np.int32]


@dataclass
class Workload:
    """One mesh with the bench's material, ready for a peer's solver."""

    name: str
    positions: Floats  # (N, 3)
    springs: Ints  # (S, 2), a < b, in the order the mesh's edges sort
    rest: Floats  # (S,)
    scale: Floats  # (N, 2): dt^2 / m and 1 - c dt / m, both 0 when pinned
    stiffness: float

    @property
    def count(self) -> int:
        return len(self.positions)

    def csr(self) -> tuple[Ints, Ints, Floats]:
        """Each vertex's springs as (offsets, other ends, rest lengths), in vertex order."""
        a, b = self.springs[:, 0], self.springs[:, 1]
        ends = np.concatenate([a, b])
        others = np.concatenate([b, a])
        rests = np.concatenate([self.rest, self.rest])
        order = np.argsort(ends, kind="stable")
        offsets = np.zeros(self.count + 1, dtype=np.int32)
        np.cumsum(np.bincount(ends, minlength=self.count), out=offsets[1:])
        return offsets, others[order].astype(np.int32), rests[order].astype(np.float32)


def unique_edges(triangles: npt.NDArray[np.int64]) -> Ints:
    """Every unique edge of the triangles, as (a, b) rows with a < b, sorted."""
    edges = np.concatenate([triangles[:, [0, 1]], triangles[:, [1, 2]], triangles[:, [2, 0]]])
    edges.sort(axis=1)
    return np.unique(edges, axis=0).astype(np.int32)


def grid_triangles(n: int) -> npt.NDArray[np.int64]:
    v = np.arange(n * n, dtype=np.int64).reshape(n, n)
    v00, v01 = v[:-1, :-1].ravel(), v[:-1, 1:].ravel()
    v10, v11 = v[1:, :-1].ravel(), v[1:, 1:].ravel()
    return np.concatenate([np.stack([v00, v10, v11], 1), np.stack([v00, v11, v01], 1)])


def grid_positions(n: int) -> Floats:
    u = np.linspace(-0.5, 0.5, n)
    x, z = np.meshgrid(u, u)  # rows run along z, columns along x, as hooke numbers them
    return np.stack([x.ravel(), np.zeros(n * n), z.ravel()], 1).astype(np.float32)


def read_ply(path: Path) -> tuple[Floats, npt.NDArray[np.int64]]:
    """Positions and triangles of a binary PLY as hooke writes it (double x y z first)."""
    data = path.read_bytes()
    end = data.index(b"end_header\n") + len(b"end_header\n")
    header = data[:end].decode("ascii").splitlines()
    if "format binary_little_endian 1.0" not in header:
        raise SystemExit(f"{path}: not a binary little-endian PLY")
    vertices = faces = 0
    properties: list[str] = []
    for line in header:
        words = line.split()
        if words[:2] == ["element", "vertex"]:
            vertices = int(words[2])
        elif words[:2] == ["element", "face"]:
            faces = int(words[2])
        elif words[:2] == ["property", "double"]:
            properties.append(words[2])
    if properties[:3] != ["x", "y", "z"]:
        raise SystemExit(f"{path}: expected double x, y, z as the first vertex properties")
    row = np.dtype([(p, "<f8") for p in properties])
    vertex_rows = np.frombuffer(data, row, vertices, end)
    face_rows = np.frombuffer(
        data, np.dtype([("n", "u1"), ("v", "<u4", 3)]), faces, end + vertices * row.itemsize
    )
    if faces == 0 or (face_rows["n"] != 3).any():
        raise SystemExit(f"{path}: expected a triangle mesh")
    positions = np.stack([vertex_rows["x"], vertex_rows["y"], vertex_rows["z"]], 1)
    return positions.astype(np.float32), face_rows["v"].astype(np.int64)


def corners(positions: Floats) -> list[int]:
    """The vertices nearest the x-z bounding box's corners (hooke's `select = ["corners"]`)."""
    lo, hi = positions.min(0), positions.max(0)
    picked = []
    for x in (lo[0], hi[0]):
        for z in (lo[2], hi[2]):
            picked.append(int(np.argmin((positions[:, 0] - x) ** 2 + (positions[:, 2] - z) ** 2)))
    return picked


def workload(name: str, positions: Floats, triangles: npt.NDArray[np.int64]) -> Workload:
    count = len(positions)
    springs = unique_edges(triangles)
    mass = 1.0 / count
    damping = 0.01 * mass / DT
    rest = np.linalg.norm(positions[springs[:, 0]] - positions[springs[:, 1]], axis=1)
    free = np.ones(count, dtype=np.float32)
    free[corners(positions)] = 0.0
    scale = np.stack([free * DT * DT / mass, free * (1.0 - damping * DT / mass)], 1)
    return Workload(
        name=name,
        positions=positions,
        springs=springs,
        rest=rest.astype(np.float32),
        scale=scale.astype(np.float32),
        stiffness=0.25 * mass / (DT * DT),
    )


def grid(n: int) -> Workload:
    return workload(f"grid {n}^2", grid_positions(n), grid_triangles(n))


def from_ply(path: Path) -> Workload:
    """The mesh of a PLY, named by its folder when hooke named the file (final-state.ply)."""
    positions, triangles = read_ply(path)
    name = path.parent.name if path.name == "final-state.ply" else path.stem
    return workload(name or path.stem, positions, triangles)
