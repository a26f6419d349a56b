"""hooke: mass-spring cloth and membranes (Georgii & Westermann, "Mass-Spring Systems on the GPU")
on any GPU through wgpu, on a multithreaded CPU, or on a float64 reference, from Python.

>>> import hooke
>>> sim = hooke.Simulation.from_scene("scenes/cloth-pinned.toml", backend="cpu")
>>> sim.step(500)
>>> sim.positions().shape
(4096, 3)
"""

from hooke._native import (
    GpuError,
    HookeError,
    InputError,
    Simulation,
    SimulationError,
    Snapshot,
    adapters,
    springs,
)

__all__ = [
    "GpuError",
    "HookeError",
    "InputError",
    "Simulation",
    "SimulationError",
    "Snapshot",
    "adapters",
    "springs",
]
