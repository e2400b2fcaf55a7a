"""A plain `pip install .` (a wheel, not an editable install) works and ships the models."""

import os
import subprocess
import sys
from pathlib import Path

import pytest

REPO = Path(__file__).resolve().parents[1]


@pytest.mark.slow
def test_wheel_install_into_a_fresh_venv_runs_from_another_folder(tmp_path):
    venv = tmp_path / "venv"
    # The venv sees the already-installed dependencies (no downloads) but gets its own copy of besman.
    subprocess.run([sys.executable, "-m", "venv", "--system-site-packages", str(venv)], check=True)
    python = venv / "bin" / "python"
    subprocess.run(
        [str(python), "-m", "pip", "install", "--quiet", "--no-deps", "--ignore-installed", str(REPO)],
        check=True,
        cwd=tmp_path,
    )
    elsewhere = tmp_path / "elsewhere"
    elsewhere.mkdir()
    environment = {key: value for key, value in os.environ.items() if key != "PYTHONPATH"}
    located = subprocess.run(
        [str(python), "-c", "import besman.robots as r; print(r.__file__)"],
        capture_output=True,
        text=True,
        check=True,
        cwd=elsewhere,
        env=environment,
    )
    assert Path(located.stdout.strip()).is_relative_to(venv), "besman came from the wheel, not the checkout"
    shown = subprocess.run(
        [str(venv / "bin" / "besman"), "robots", "show", "aila", "--json"],
        capture_output=True,
        text=True,
        check=True,
        cwd=elsewhere,
        env=environment,
    )
    assert '"J_Shoulder1_r"' in shown.stdout
