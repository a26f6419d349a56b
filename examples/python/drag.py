"""Driving a simulation from Python each frame: a drag pulls one vertex of the Fig. 2 cloth
around a circle, as a mouse would, and the script reports how closely the cloth follows.
Writes the last frame as a PLY (as `hooke run` does) and, with a GPU, a PNG.

    python examples/python/drag.py [--frames 120] [--out drag-out]
"""

import argparse
import math
from pathlib import Path

import numpy as np

import hooke

SCENES = Path(__file__).resolve().parents[2] / "scenes"


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__)
    parser.add_argument("--frames", type=int, default=120)
    parser.add_argument("--steps-per-frame", type=int, default=20)
    parser.add_argument("--out", type=Path, default=Path("drag-out"))
    args = parser.parse_args()
    args.out.mkdir(parents=True, exist_ok=True)

    sim = hooke.Simulation.from_scene(SCENES / "cloth-pinned.toml")
    positions = sim.positions()
    grabbed = int(np.argmin(np.linalg.norm(positions - positions.mean(axis=0), axis=1)))
    centre = positions[grabbed].astype(float)
    distances = []
    for frame in range(args.frames):
        angle = 2.0 * math.pi * frame / args.frames
        target = centre + 0.2 * np.array([math.cos(angle), 0.3, math.sin(angle)])
        sim.set_drags([(grabbed, tuple(target), 40.0)])  # written in place: nothing rebuilt
        sim.step(args.steps_per_frame)
        distances.append(float(np.linalg.norm(sim.positions()[grabbed] - target)))
    print(
        f"{args.frames} frames: the grabbed vertex trails its target by "
        f"{100 * np.median(distances):.1f} cm (median)"
    )
    sim.write_frame(args.out / "last-frame.ply")
    if hooke.adapters():
        sim.save_png(args.out / "last-frame.png", 480, 270)
        print(f"frame in {args.out}/last-frame.ply and .png")
    else:
        print(f"frame in {args.out}/last-frame.ply (no GPU to draw a PNG)")


if __name__ == "__main__":
    main()
