"""bench/versus_taichi.py: its pairing and both readings of the speed-up, and a whole run of it
against the real `hooke bench` with a stand-in for the Taichi peer (Taichi itself is not
installed for the tests)."""

import sys
import textwrap
from pathlib import Path

import pytest
from conftest import ROOT, hooke_binary

sys.path.insert(0, str(ROOT / "bench"))
import versus_taichi  # noqa: E402  (a script beside the peers, not a package)


def test_each_method_is_paired_with_taichis_same_method_round_by_round() -> None:
    hooke = [
        {("grid 8^2", "gather"): 1.0, ("grid 8^2", "scatter/incidence"): 2.0},
        {("grid 8^2", "gather"): 2.0, ("grid 8^2", "scatter/incidence"): 2.0},
        {("grid 8^2", "gather"): 4.0, ("grid 8^2", "scatter/incidence"): 2.0},
    ]
    # Taichi fast when hooke is slow: medians taken apart pair one's fast rounds with the
    # other's slow ones, and read differently from the rounds' own ratios.
    taichi = [
        {("grid 8^2", "gather"): 8.0, ("grid 8^2", "scatter"): 3.0},
        {("grid 8^2", "gather"): 2.0, ("grid 8^2", "scatter"): 5.0},
        {("grid 8^2", "gather"): 3.0, ("grid 8^2", "scatter"): 4.0},
    ]
    gather, incidence = versus_taichi.compare(hooke, taichi)
    assert (gather.method, gather.peer) == ("gather", "gather")
    assert (incidence.method, incidence.peer) == ("scatter/incidence", "scatter")
    assert gather.apart == pytest.approx(3.0 / 2.0)
    assert gather.ratios == pytest.approx([8.0, 1.0, 0.75])
    assert incidence.apart == pytest.approx(2.0)
    rows = versus_taichi.table([gather, incidence]).splitlines()
    assert rows[2].endswith("| 1.50 | 1.00 (0.75-8.00) | 2 of 3 |"), rows[2]
    assert rows[3].endswith("| 2.00 | 2.00 (1.50-2.50) | 0 of 3 |"), rows[3]


def test_a_pair_missing_from_a_round_is_an_error() -> None:
    hooke = [{("grid 8^2", "gather"): 1.0}, {("grid 8^2", "gather"): 1.0}]
    taichi = [{("grid 8^2", "gather"): 2.0}, {("grid 8^2", "scatter"): 2.0}]
    with pytest.raises(ValueError, match="round 2 has no grid 8\\^2 gather"):
        versus_taichi.compare(hooke, taichi)


def test_a_report_row_without_its_timing_names_the_field() -> None:
    report: dict[str, object] = {"rows": [{"mesh": "grid 8^2", "method": "gather"}]}
    with pytest.raises(SystemExit, match="the peer's grid 8\\^2 gather has no `ms_per_step`"):
        versus_taichi.timings(report, "ms_per_step", "the peer")
    with pytest.raises(SystemExit, match="the peer printed no `rows`"):
        versus_taichi.timings({}, "ms_per_step", "the peer")


# Stands in for taichi_peer.py: its arguments, its banner line, and JSON of its shape, every
# method taking 1 s a step (so hooke's speed-up is large in every round).
FAKE_PEER = """
import argparse, json
parser = argparse.ArgumentParser()
for name in ("--arch", "--sizes", "--methods", "--steps", "--repeats", "--format"):
    parser.add_argument(name)
args = parser.parse_args()
assert args.format == "json" and args.arch == "vulkan"
print("[Taichi] version 0.0.0, a stand-in")
rows = [
    {"mesh": f"grid {n}^2", "method": m, "ms_per_step": 1000.0}
    for n in args.sizes.split(",") for m in args.methods.split(",")
]
print(json.dumps({"rows": rows}))
"""


@pytest.mark.usefixtures("gpu")
def test_a_run_times_hooke_and_the_peer_in_turn_and_prints_both_readings(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    peer = tmp_path / "peer.py"
    peer.write_text(textwrap.dedent(FAKE_PEER))
    versus_taichi.main(
        [
            *["--rounds", "2", "--sizes", "8,12", "--steps", "5", "--repeats", "1"],
            *["--methods", "gather,incidence", "--hooke", str(hooke_binary())],
            *["--peer-python", sys.executable, "--peer", str(peer)],
        ]
    )
    out = capsys.readouterr().out
    rows = [line for line in out.splitlines() if line.startswith("| grid")]
    assert [row.split("|")[1:4] for row in rows] == [
        [" grid 8^2 ", " gather ", " gather "],
        [" grid 8^2 ", " scatter/incidence ", " scatter "],
        [" grid 12^2 ", " gather ", " gather "],
        [" grid 12^2 ", " scatter/incidence ", " scatter "],
    ]
    for row in rows:
        hooke_ms = float(row.split("|")[4].split()[0])
        assert 0.0 < hooke_ms < 1000.0, row
        assert row.endswith("| 0 of 2 |"), row
