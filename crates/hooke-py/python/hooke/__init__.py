"""hooke: mass-spring cloth and membranes (Georgii & Westermann, "Mass-Spring Systems on the GPU")
on any GPU through wgpu, on a multithreaded CPU, or on a float64 reference, from Python.

>>> import hooke
>>> sim = hooke.Simulation.from_scene("scenes/cloth-pinned.toml", backend="cpu")
>>> sim.step(500)
>>> sim.positions().shape
(4096, 3)
>>> with hooke.FrameWriter(sim, "out/cloth.usda", frame_every=10) as frames:
...     for _ in range(5):
...         sim.step(10)
...         frames.write()
"""

from hooke._native import (
    FrameWriter,
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
    "FrameWriter",
    "GpuError",
    "HookeError",
    "InputError",
    "Simulation",
    "SimulationError",
    "Snapshot",
    "adapters",
    "springs",
]
