"""The examples run as a user would run them (with fewer steps) and write what they promise."""

import subprocess
import sys
from pathlib import Path

import pytest
from conftest import ROOT

EXAMPLES = ROOT / "examples" / "python"


@pytest.mark.parametrize(
    ("script", "args", "outputs"),
    [
        ("fig2_sag.py", ["--steps", "600", "--out", "sag.png"], ["sag.png"]),
        (
            "stiffness_sweep.py",
            ["--steps", "300", "--size", "10", "--out", "sweep.png"],
            ["sweep.png"],
        ),
        ("drag.py", ["--frames", "10", "--out", "drag"], ["drag/last-frame.ply"]),
    ],
)
def test_example_runs_and_writes_its_output(
    tmp_path: Path, script: str, args: list[str], outputs: list[str]
) -> None:
    result = subprocess.run(
        [sys.executable, str(EXAMPLES / script), *args],
        cwd=tmp_path,
        capture_output=True,
        text=True,
        check=False,
    )
    assert result.returncode == 0, result.stderr
    for output in outputs:
        assert (tmp_path / output).stat().st_size > 0, output
