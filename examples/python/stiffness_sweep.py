"""A parameter sweep: the final sag of a pinned cloth against its spring stiffness, one
simulation per stiffness, built from numpy arrays. Prints a table and saves a plot.

    python examples/python/stiffness_sweep.py [--steps 4000] [--out sweep.png]
"""

import argparse
from pathlib import Path

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt
import numpy as np
import numpy.typing as npt

import hooke


def sheet(n: int) -> tuple[npt.NDArray[np.float64], npt.NDArray[np.int64]]:
    """An n x n grid, 1 m wide, in the x-z plane at 1 m height."""
    xs = np.linspace(-0.5, 0.5, n)
    vertices = np.array([[x, 1.0, z] for z in xs for x in xs])
    triangles = []
    for r in range(n - 1):
        for c in range(n - 1):
            a, b, d = r * n + c, r * n + c + 1, (r + 1) * n + c
            triangles += [[a, d, b], [b, d, d + 1]]
    return vertices, np.array(triangles)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__)
    parser.add_argument("--steps", type=int, default=4000)
    parser.add_argument("--size", type=int, default=24, help="vertices per side")
    parser.add_argument("--out", type=Path, default=Path("sweep.png"))
    args = parser.parse_args()

    vertices, triangles = sheet(args.size)
    middle = len(vertices) // 2 + args.size // 2
    stiffnesses = [50.0, 100.0, 200.0, 400.0, 800.0]
    sags = []
    print("stiffness N/m   final sag cm")
    for stiffness in stiffnesses:
        sim = hooke.Simulation.from_arrays(
            vertices,
            triangles,
            stiffness=stiffness,
            mass_total=0.2,
            damping=0.002,
            select=["corners"],
        )
        sim.step(args.steps)
        sag = float(vertices[middle, 1] - sim.positions()[middle, 1]) * 100.0
        sags.append(sag)
        print(f"{stiffness:13.0f}   {sag:12.3f}")

    figure, axes = plt.subplots(figsize=(5, 3.5))
    axes.loglog(stiffnesses, sags, "o-")
    axes.set_xlabel("spring stiffness (N/m)")
    axes.set_ylabel("sag of the middle (cm)")
    figure.tight_layout()
    figure.savefig(args.out, dpi=100)
    print(f"plot in {args.out}")


if __name__ == "__main__":
    main()
