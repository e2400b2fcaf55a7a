"""What several test files share: running the command line and the benchmarks, comparing rotations."""

from __future__ import annotations

import json
import subprocess
import sys
from pathlib import Path

import numpy as np

from besman.cli import main

BENCHMARKS = Path(__file__).resolve().parents[1] / "benchmarks"


def run_cli(capsys, *argv: str) -> tuple[int, str, str]:
    """``besman ARGV`` in this process: (exit code, stdout, stderr)."""
    code = main(list(argv))
    captured = capsys.readouterr()
    return code, captured.out, captured.err


def run_benchmark(script: str, *argv: str) -> dict:
    """The JSON report of ``benchmarks/SCRIPT --json ARGV`` (a failing script fails the test)."""
    result = subprocess.run(
        [sys.executable, str(BENCHMARKS / script), "--json", *argv],
        capture_output=True,
        text=True,
        check=True,
    )
    return json.loads(result.stdout)


def rotation_angle(q1, q2) -> np.ndarray:
    """The angle (rad) between rotations given as (w, x, y, z) quaternions (q and -q are the same)."""
    dot = np.abs(np.sum(np.asarray(q1) * np.asarray(q2), axis=-1))
    return 2.0 * np.arccos(np.clip(dot, 0.0, 1.0))
