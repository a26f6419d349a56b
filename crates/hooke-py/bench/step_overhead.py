"""What stepping from Python costs over stepping from Rust: the same scene, solver and batches
of steps through `sim.step(batch)` in a Python loop and through the Rust API, alternated.

    cargo build --release -p hooke --example step_timing
    ./run python          # the release wheel
    .venv/bin/python crates/hooke-py/bench/step_overhead.py [--runs 9] [--steps 4000]

Prints each run and the medians. A benchmark, not a test: it asserts nothing.
"""

import argparse
import statistics
import subprocess
import time
from pathlib import Path

import hooke

ROOT = Path(__file__).resolve().parents[3]


def python_ms_per_step(scene: Path, steps: int, batch: int) -> float:
    sim = hooke.Simulation.from_scene(scene, backend="cpu", method="gather")
    sim.step(batch)  # warm-up
    start = time.perf_counter()
    for _ in range(steps // batch):
        sim.step(batch)
    return (time.perf_counter() - start) * 1e3 / (steps // batch * batch)


def rust_ms_per_step(binary: Path, scene: Path, steps: int, batch: int) -> float:
    out = subprocess.run(
        [str(binary), str(scene), str(steps), str(batch)],
        check=True,
        capture_output=True,
        text=True,
    ).stdout
    return float(out.split()[-1])


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__)
    parser.add_argument("--scene", type=Path, default=ROOT / "scenes" / "bench-grid-256.toml")
    parser.add_argument("--steps", type=int, default=4000)
    parser.add_argument("--batch", type=int, default=100)
    parser.add_argument("--runs", type=int, default=9)
    parser.add_argument(
        "--binary", type=Path, default=ROOT / "target" / "release" / "examples" / "step_timing"
    )
    args = parser.parse_args()
    if not args.binary.exists():
        parser.error(
            f"{args.binary} is missing: cargo build --release -p hooke --example step_timing"
        )
    python, rust = [], []
    print(f"{args.scene.name}, cpu gather, {args.steps} steps in batches of {args.batch}")
    for run in range(args.runs):
        python.append(python_ms_per_step(args.scene, args.steps, args.batch))
        rust.append(rust_ms_per_step(args.binary, args.scene, args.steps, args.batch))
        print(f"run {run + 1}: python {python[-1]:.4f} ms/step, rust {rust[-1]:.4f} ms/step")
    p, r = statistics.median(python), statistics.median(rust)
    print(
        f"median: python {p:.4f} ms/step ({min(python):.4f} to {max(python):.4f}), "
        f"rust {r:.4f} ms/step ({min(rust):.4f} to {max(rust):.4f}); "
        f"python / rust = {p / r:.3f}"
    )


if __name__ == "__main__":
    main()
