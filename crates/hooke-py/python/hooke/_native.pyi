"""Types of hooke's native module (Rust, PyO3). Units are SI: m, kg, s, N."""

from collections.abc import Sequence
from os import PathLike
from typing import Any, Literal, TypeAlias

import numpy as np
import numpy.typing as npt

Vec3: TypeAlias = tuple[float, float, float] | Sequence[float]
Backend: TypeAlias = Literal["reference", "cpu", "gpu"]
Method: TypeAlias = Literal["gather", "scatter"]
Accumulation: TypeAlias = Literal[
    "atomic-f32", "atomic-fixed", "incidence", "blend-r32f", "blend-r16f", "blend-rgba8"
]

class HookeError(Exception):
    """Every error hooke raises is a HookeError."""

class InputError(HookeError):
    """A scene, mesh, array or argument hooke cannot take; the message says which and why."""

class SimulationError(HookeError):
    """The simulation left the numbers, or a fixed-point sum overflowed."""

class GpuError(HookeError):
    """No GPU adapter, a missing optional feature, or a device error."""

class Snapshot:
    """A saved state (positions, previous positions, balls, step counter, torn springs) to
    restore later."""

    @property
    def steps_taken(self) -> int: ...
    @property
    def broken_spring_count(self) -> int:
        """How many springs had torn when the snapshot was taken."""

class Simulation:
    """A mass-spring simulation on the float64 reference, the CPU or the GPU solver."""

    @staticmethod
    def from_scene(
        path: str | PathLike[str],
        *,
        backend: Backend = "cpu",
        method: Method | None = None,
        accumulation: Accumulation | None = None,
        threads: int | None = None,
        allow_unstable: bool = False,
    ) -> Simulation:
        """A simulation of a scene file (TOML), on the solver named as on the CLI."""

    @staticmethod
    def from_arrays(
        vertices: npt.ArrayLike,
        triangles: npt.ArrayLike,
        *,
        stiffness: float | npt.ArrayLike,
        mass_total: float | None = None,
        mass_per_vertex: float | npt.ArrayLike | None = None,
        area_density: float | None = None,
        stiffness_model: Literal["uniform", "inverse-rest-length"] = "uniform",
        damping: float = 0.0,
        pins: Sequence[int] | None = None,
        select: Sequence[Literal["corners", "top-corners", "top-edge"]] | None = None,
        dt: float | None = None,
        gravity: Vec3 = (0.0, -9.81, 0.0),
        wind: dict[str, Any] | None = None,
        thickness: float = 0.0,
        colliders: Sequence[dict[str, Any]] | None = None,
        self_collision: dict[str, Any] | None = None,
        bending: dict[str, Any] | None = None,
        handles: Sequence[dict[str, Any]] | None = None,
        tearing: dict[str, Any] | None = None,
        uvs: npt.ArrayLike | None = None,
        backend: Backend = "cpu",
        method: Method | None = None,
        accumulation: Accumulation | None = None,
        threads: int | None = None,
        allow_unstable: bool = False,
    ) -> Simulation:
        """A simulation of vertices (N, 3) and triangles (T, 3), with a scene file's settings
        as keywords. dt=None is 0.9 of the stability bound. uvs (N, 2), texture coordinates
        per vertex, go into the frames."""

    @property
    def name(self) -> str: ...
    @property
    def vertex_count(self) -> int: ...
    @property
    def spring_count(self) -> int: ...
    @property
    def bending_spring_count(self) -> int:
        """Of spring_count, the bending springs: the last ones in springs()."""
    def broken_springs(self) -> npt.NDArray[np.uint32]:
        """The springs torn so far (indices into springs()), in order: a (B,) array."""
    @property
    def steps_taken(self) -> int: ...
    @property
    def time(self) -> float: ...
    @property
    def dt(self) -> float: ...
    @property
    def damping(self) -> float: ...
    @property
    def stiffness_scale(self) -> float: ...
    @property
    def gravity(self) -> tuple[float, float, float]: ...
    def describe(self) -> str: ...
    def step(self, steps: int) -> None:
        """Advances `steps` steps, with the GIL released."""

    def check(self) -> None: ...
    def positions(self) -> npt.NDArray[np.float32]: ...
    def previous_positions(self) -> npt.NDArray[np.float32]: ...
    def set_positions(
        self, positions: npt.ArrayLike, previous: npt.ArrayLike | None = None
    ) -> None: ...
    def snapshot(self) -> Snapshot: ...
    def restore(self, snapshot: Snapshot) -> None: ...
    def save_state(self, path: str | PathLike[str]) -> None: ...
    def load_state(self, path: str | PathLike[str]) -> None: ...
    def write_frame(self, path: str | PathLike[str]) -> None: ...
    def set_drags(self, drags: Sequence[tuple[int | Sequence[int], Vec3, float]]) -> None: ...
    def set_point_forces(self, forces: Sequence[tuple[int, Vec3]]) -> None: ...
    def set_wind(self, velocity: Vec3 | None, coefficient: float = 0.5) -> None: ...
    def set_ball_forces(self, forces: Sequence[tuple[int, Vec3]]) -> None: ...
    def set_material(
        self,
        *,
        dt: float | None = None,
        damping: float | None = None,
        stiffness_scale: float | None = None,
        gravity: Vec3 | None = None,
        allow_unstable: bool = False,
    ) -> None: ...
    def set_self_collision(self, settings: dict[str, Any] | None) -> None: ...
    def pin(self, vertex: int, at: Vec3 | None = None) -> None:
        """Pins vertex where it is, or at `at` (m, at rest), until unpin; carries the run on."""
    def unpin(self, vertex: int) -> None:
        """Lets a pinned vertex (a scene pin too) move again, from rest where it is."""
    def energy(self) -> dict[str, float]: ...
    def max_strain(self) -> tuple[float, int]:
        """The largest strain |l| / l0 - 1 of any spring still whole, and its index."""
    def pin_reactions(
        self,
    ) -> tuple[npt.NDArray[np.uint32], npt.NDArray[np.float64]]: ...
    def colliders(self) -> list[dict[str, Any]]: ...
    def stable_dt(self) -> tuple[float, int | None]: ...
    def memory(self) -> dict[str, int]: ...
    def step_timed(self) -> dict[str, Any]: ...
    def steps_timed(self, steps: int) -> list[dict[str, Any]]:
        """`steps` steps each timed as step_timed times one (a GPU records 10 to a submission)."""
    def triangles(self) -> npt.NDArray[np.uint32]: ...
    def springs(self) -> npt.NDArray[np.uint32]: ...
    def pins(self) -> list[int]: ...
    def render(
        self, width: int = 640, height: int = 360, *, strain: bool = False, wireframe: bool = False
    ) -> npt.NDArray[np.uint8]: ...
    def save_png(
        self,
        path: str | PathLike[str],
        width: int = 640,
        height: int = 360,
        *,
        strain: bool = False,
        wireframe: bool = False,
    ) -> None: ...

FrameFormat: TypeAlias = Literal["ply", "obj", "pc2", "usda"]

class FrameWriter:
    """Frames of a simulation in the formats `hooke run` writes. `output` is a directory
    (frame-NNNNNNN.ply/.obj, frames.pc2, frames.usda) or a .usda/.pc2 file; format defaults to
    the file's extension, else "ply". A .pc2 or .usda file appears when the writer is closed
    (also on leaving a `with` block, or when the writer is collected)."""

    def __init__(
        self,
        simulation: Simulation,
        output: str | PathLike[str],
        *,
        format: FrameFormat | None = None,
        frame_every: int = 1,
    ) -> None: ...
    def write(self) -> None:
        """Adds the simulation's current state as the frame of its step counter."""
    def close(self) -> int:
        """Completes the output; returns the number of frames written."""
    @property
    def frames_written(self) -> int: ...
    @property
    def path(self) -> PathLike[str]: ...
    def __enter__(self) -> FrameWriter: ...  # noqa: PYI034 (typing.Self needs Python 3.11)
    def __exit__(self, *exc: object) -> bool: ...

def adapters() -> list[dict[str, Any]]: ...
def springs(triangles: npt.ArrayLike) -> npt.NDArray[np.uint32]: ...
