"""hooke's GPU methods against Taichi's on the same driver, round by round.

Issue 14's target: every hooke GPU method at least 1.5x faster than Taichi's Vulkan backend's
same method. A round runs `hooke bench --backend gpu` over the sizes, then the Taichi peer
(taichi_peer.py) over the same sizes. Each hooke method is paired with Taichi's same method:
gather with gather, every scatter accumulation with Taichi's atomic scatter. The table gives
the speed-up two ways: median against median, and the median and range of the rounds' own
ratios. On a machine whose speed changes from minute to minute (this project's VMs run in a
fast and a slow state, about 2x apart) the second is the fairer reading: medians taken apart
can pair one program's fast rounds with the other's slow ones.

Run it with `./run versus-taichi [--rounds N] [--sizes ...]`, which builds hooke and installs
Taichi first, or directly: `python bench/versus_taichi.py --hooke target/release/hooke
--peer-python .venv-taichi/bin/python`.
"""

from __future__ import annotations

import argparse
import json
import statistics
import subprocess
import sys
from dataclasses import dataclass
from pathlib import Path

TARGET = 1.5
HERE = Path(__file__).resolve().parent

# (mesh, method) -> ms per step, one program's round.
Timings = dict[tuple[str, str], float]


def peer_method(hooke_method: str) -> str:
    """Taichi's method to compare a hooke GPU method with (hooke names a scatter method by its
    accumulation, `scatter/atomic-f32`; Taichi's only scatter sums with atomic adds)."""
    return "gather" if hooke_method == "gather" else "scatter"


@dataclass(frozen=True)
class Comparison:
    """One hooke method on one mesh against Taichi's, over the same rounds."""

    mesh: str
    method: str
    peer: str
    hooke_ms: list[float]
    peer_ms: list[float]

    @property
    def apart(self) -> float:
        """Taichi's median over hooke's: the speed-up, medians taken apart."""
        return statistics.median(self.peer_ms) / statistics.median(self.hooke_ms)

    @property
    def ratios(self) -> list[float]:
        """Each round's speed-up: Taichi's time over hooke's in that round."""
        return [p / h for h, p in zip(self.hooke_ms, self.peer_ms, strict=True)]


def compare(hooke_rounds: list[Timings], peer_rounds: list[Timings]) -> list[Comparison]:
    """Pairs every hooke row of the first round with Taichi's same method on the same mesh,
    across the rounds; a pair missing from any round is an error."""
    if not hooke_rounds or len(hooke_rounds) != len(peer_rounds):
        raise ValueError("need the same number (at least one) of hooke and Taichi rounds")
    comparisons = []
    for mesh, method in hooke_rounds[0]:
        peer = peer_method(method)
        hooke_ms, peer_ms = [], []
        for index, (hooke, taichi) in enumerate(zip(hooke_rounds, peer_rounds, strict=True)):
            if (mesh, method) not in hooke or (mesh, peer) not in taichi:
                raise ValueError(f"round {index + 1} has no {mesh} {method} / Taichi {peer}")
            hooke_ms.append(hooke[(mesh, method)])
            peer_ms.append(taichi[(mesh, peer)])
        comparisons.append(Comparison(mesh, method, peer, hooke_ms, peer_ms))
    return comparisons


def spread(values: list[float], digits: int) -> str:
    """`median (min-max)`."""
    return (
        f"{statistics.median(values):.{digits}f}"
        f" ({min(values):.{digits}f}-{max(values):.{digits}f})"
    )


def table(comparisons: list[Comparison], target: float = TARGET) -> str:
    """The comparisons as a Markdown table, the speed-ups both ways."""
    lines = [
        "| mesh | hooke method | Taichi method | hooke ms/step | Taichi ms/step "
        "| speed-up, medians apart | speed-up by rounds | rounds below "
        f"{target:g} |",
        "|---|---|---|---|---|---|---|---|",
    ]
    for c in comparisons:
        below = sum(r < target for r in c.ratios)
        lines.append(
            f"| {c.mesh} | {c.method} | {c.peer} | {spread(c.hooke_ms, 3)} "
            f"| {spread(c.peer_ms, 3)} | {c.apart:.2f} | {spread(c.ratios, 2)} "
            f"| {below} of {len(c.ratios)} |"
        )
    return "\n".join(lines)


def run_json(command: list[str]) -> dict[str, object]:
    """Runs `command` and reads the JSON object its standard output ends with (Taichi prints
    lines of its own before it, on import and on start)."""
    result = subprocess.run(command, capture_output=True, text=True, check=False)
    shown = " ".join(command)
    if result.returncode != 0:
        raise SystemExit(
            f"versus_taichi.py: `{shown}` failed ({result.returncode}):\n{result.stderr.strip()}"
        )
    start = result.stdout.find("\n{") + 1 if not result.stdout.startswith("{") else 0
    try:
        report = json.loads(result.stdout[start:])
    except json.JSONDecodeError as error:
        raise SystemExit(f"versus_taichi.py: `{shown}` printed no JSON object ({error})") from None
    if not isinstance(report, dict):
        raise SystemExit(f"versus_taichi.py: `{shown}` printed no JSON object")
    return report


def timings(report: dict[str, object], field: str, source: str) -> Timings:
    """A report's rows as timings: each row's `mesh`, `method` and the milliseconds in
    `field`. A row without them is an error naming the field and the program."""
    rows = report.get("rows")
    if not isinstance(rows, list):
        raise SystemExit(f"versus_taichi.py: {source} printed no `rows`")
    found: Timings = {}
    for row in rows:
        fields = row if isinstance(row, dict) else {}
        mesh, method, ms = fields.get("mesh"), fields.get("method"), fields.get(field)
        if not isinstance(mesh, str) or not isinstance(method, str):
            raise SystemExit(f"versus_taichi.py: a row of {source} without `mesh` or `method`")
        if not isinstance(ms, int | float):
            raise SystemExit(f"versus_taichi.py: {source}'s {mesh} {method} has no `{field}`")
        found[(mesh, method)] = float(ms)
    return found


def hooke_round(args: argparse.Namespace) -> Timings:
    command = [
        *[str(args.hooke), "bench", "--backend", "gpu", "--sizes", args.sizes],
        *["--irregular", "0", "--shuffled", "0", "--gpu-methods", args.methods],
        *["--steps", str(args.steps), "--format", "json"],
    ]
    return timings(run_json(command), "total_ms", "hooke bench")


def peer_round(args: argparse.Namespace, methods: str) -> Timings:
    command = [
        *[str(args.peer_python), str(args.peer), "--arch", "vulkan", "--sizes", args.sizes],
        *["--methods", methods, "--steps", str(args.steps)],
        *["--repeats", str(args.repeats), "--format", "json"],
    ]
    return timings(run_json(command), "ms_per_step", "the Taichi peer")


def main(argv: list[str] | None = None) -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--rounds", type=int, default=9, help="rounds of both programs")
    parser.add_argument("--sizes", default="128,256,512", help="grid sides, comma-separated")
    parser.add_argument(
        "--methods",
        default="gather,atomic-f32,incidence",
        help="hooke's GPU methods (`hooke bench --gpu-methods`)",
    )
    parser.add_argument("--steps", type=int, default=100, help="timed steps per block")
    parser.add_argument("--repeats", type=int, default=5, help="Taichi's timed blocks")
    parser.add_argument("--hooke", type=Path, default=Path("target/release/hooke"))
    parser.add_argument("--peer-python", type=Path, default=Path(sys.executable))
    parser.add_argument("--peer", type=Path, default=HERE / "taichi_peer.py")
    args = parser.parse_args(argv)
    if args.rounds < 1:
        parser.error("--rounds must be at least 1")
    peer_methods = sorted({peer_method(m) for m in args.methods.split(",")})
    hooke_rounds, peer_rounds = [], []
    for index in range(args.rounds):
        print(f"round {index + 1} of {args.rounds}: hooke, then Taichi", file=sys.stderr)
        hooke_rounds.append(hooke_round(args))
        peer_rounds.append(peer_round(args, ",".join(peer_methods)))
    try:
        comparisons = compare(hooke_rounds, peer_rounds)
    except ValueError as error:
        raise SystemExit(f"versus_taichi.py: {error}") from None
    rounds = f"{args.rounds} round{'' if args.rounds == 1 else 's'}"
    print(
        f"hooke's GPU methods against Taichi's on the same driver, {rounds} of "
        f"{args.steps} steps; speed-up: Taichi's time over hooke's (target {TARGET:g})"
    )
    print(table(comparisons))


if __name__ == "__main__":
    main()
