"""Shared fixtures: the repository, the release binaries, the real drives
beside the repository (``../shared``) and simulated drives written by
``sensor-bridge simulate``. Each skips with its reason printed when what it
needs is absent."""

from __future__ import annotations

import json
import os
import subprocess
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[3]
# `../shared` beside the repository (WHEELCAL_SHARED_DIR: elsewhere, e.g.
# a folder that does not exist, to see the tests skip).
SHARED = Path(os.environ.get("WHEELCAL_SHARED_DIR", ROOT.parent / "shared"))
RELEASE = ROOT / "target" / "release"


def skip(reason: str):
    print(f"skipped: {reason}")
    pytest.skip(reason)


def binary(name: str) -> Path:
    """A release binary of the workspace (built by `cargo build --release`)."""
    path = RELEASE / name
    if not path.is_file():
        skip(f"{path} is absent: run `cargo build --release` first")
    return path


def real_drive(name: str) -> Path:
    path = SHARED / "data" / "real" / name
    if not path.is_dir():
        skip(f"the real drive {path} is absent")
    return path


def cli_json(args: list[str], json_path: Path | None = None) -> dict:
    """Run a CLI; its JSON (written to json_path, or printed)."""
    out = subprocess.run(args, capture_output=True, text=True)
    assert out.returncode == 0, out.stderr
    if json_path is None:
        return json.loads(out.stdout)
    return json.loads(json_path.read_text())


def cli_error(args: list[str]) -> str:
    """Run a CLI expected to fail; its standard error."""
    out = subprocess.run(args, capture_output=True, text=True)
    assert out.returncode != 0, out.stdout
    return out.stderr


def simulate(out: Path, *, seed: int = 1, duration_s: float = 300.0, scenario: str = "mixed", extra=()) -> Path:
    """A simulated drive folder (sensor-bridge simulate)."""
    args = [
        str(binary("sensor-bridge")),
        "simulate",
        "--scenario",
        scenario,
        "--seed",
        str(seed),
        "--duration",
        str(duration_s),
        "--out",
        str(out),
        *extra,
    ]
    done = subprocess.run(args, capture_output=True, text=True)
    assert done.returncode == 0, done.stderr
    return out


@pytest.fixture(scope="session")
def sim_drive(tmp_path_factory) -> Path:
    return simulate(tmp_path_factory.mktemp("sim") / "drive", seed=5, duration_s=300.0)
