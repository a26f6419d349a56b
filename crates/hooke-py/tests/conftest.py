"""Shared fixtures: the repository's scenes, the `hooke` binary, and whether a GPU is there."""

import os
import subprocess
from pathlib import Path
from typing import Literal

import pytest

import hooke

ROOT = Path(__file__).resolve().parents[3]
SCENES = ROOT / "scenes"


def hooke_binary() -> Path:
    """The CLI built from this checkout (HOOKE_BIN, else the dev build)."""
    return Path(os.environ.get("HOOKE_BIN", ROOT / "target" / "debug" / "hooke"))


def run_cli(*args: str) -> subprocess.CompletedProcess[str]:
    """Runs `hooke ARGS` and requires success."""
    result = subprocess.run(
        [str(hooke_binary()), *args], capture_output=True, text=True, check=False
    )
    assert result.returncode == 0, result.stderr
    return result


def gpu_available() -> bool:
    """Whether a GPU adapter exists; under HOOKE_REQUIRE_GPU=1 its absence fails the test."""
    try:
        return bool(hooke.adapters())
    except hooke.HookeError:
        return False


@pytest.fixture
def gpu() -> None:
    """Skips a GPU test without an adapter, or fails it when HOOKE_REQUIRE_GPU=1."""
    if not gpu_available():
        if os.environ.get("HOOKE_REQUIRE_GPU") == "1":
            pytest.fail("HOOKE_REQUIRE_GPU=1 but no GPU adapter")
        pytest.skip("no GPU adapter")


@pytest.fixture(params=["cpu", "gpu"])
def backend(request: pytest.FixtureRequest) -> Literal["cpu", "gpu"]:
    """Each solver backend in turn; the GPU's run is skipped or failed as `gpu` says."""
    name: Literal["cpu", "gpu"] = request.param
    if name == "gpu":
        request.getfixturevalue("gpu")
    return name
