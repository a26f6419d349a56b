"""The paper's Fig. 2: a cloth pinned at its four corners sags under gravity. Plots the sag of
its middle over time and saves the plot as a PNG.

    python examples/python/fig2_sag.py [--steps 6000] [--out fig2-sag.png] [--backend cpu]
"""

import argparse
from pathlib import Path

import matplotlib

matplotlib.use("Agg")  # files only: no display needed
import matplotlib.pyplot as plt
import numpy as np

import hooke

SCENES = Path(__file__).resolve().parents[2] / "scenes"


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__)
    parser.add_argument("--steps", type=int, default=6000)
    parser.add_argument("--every", type=int, default=100, help="steps between samples")
    parser.add_argument("--backend", default="cpu", choices=["reference", "cpu", "gpu"])
    parser.add_argument("--out", type=Path, default=Path("fig2-sag.png"))
    args = parser.parse_args()

    sim = hooke.Simulation.from_scene(SCENES / "cloth-pinned.toml", backend=args.backend)
    start = sim.positions()
    # The vertex nearest the middle of the sheet (in x and z).
    middle = int(np.argmin(np.linalg.norm(start[:, [0, 2]] - start[:, [0, 2]].mean(0), axis=1)))
    times, sags = [0.0], [0.0]
    for _ in range(args.steps // args.every):
        sim.step(args.every)
        times.append(sim.time)
        sags.append(float(start[middle, 1] - sim.positions()[middle, 1]) * 100.0)

    figure, axes = plt.subplots(figsize=(6, 3.5))
    axes.plot(times, sags)
    axes.set_xlabel("time (s)")
    axes.set_ylabel("sag of the middle (cm)")
    axes.set_title(f"Fig. 2 cloth, {sim.vertex_count} vertices, {sim.describe()}")
    figure.tight_layout()
    figure.savefig(args.out, dpi=100)
    print(f"sag after {sim.time:.2f} s: {sags[-1]:.2f} cm; plot in {args.out}")


if __name__ == "__main__":
    main()
