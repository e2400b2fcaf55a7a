"""A plain `pip install .` (a wheel, not an editable install) works and ships the models."""

import os
import site
import subprocess
import sys
from pathlib import Path

import pytest

REPO = Path(__file__).resolve().parents[1]


def run(*argv, **options) -> subprocess.CompletedProcess:
    """A command that must succeed; its stderr is part of the failure message."""
    result = subprocess.run([str(a) for a in argv], capture_output=True, text=True, **options)
    assert result.returncode == 0, f"{' '.join(map(str, argv))} failed:\n{result.stderr}"
    return result


@pytest.mark.slow
def test_wheel_install_into_a_fresh_venv_runs_from_another_folder(tmp_path):
    venv = tmp_path / "venv"
    # The venv sees the already-installed dependencies (no downloads) but gets its own copy of besman.
    # --system-site-packages shows the base interpreter's packages; inside a virtual environment the
    # dependencies live in that environment instead, so its site-packages are added by a .pth file (plain
    # paths: the editable besman's own .pth hooks there are not run).
    run(sys.executable, "-m", "venv", "--system-site-packages", venv)
    python = venv / "bin" / "python"
    if sys.prefix != sys.base_prefix:
        purelib = run(
            python, "-c", "import sysconfig; print(sysconfig.get_paths()['purelib'])"
        ).stdout.strip()
        Path(purelib, "outer_environment.pth").write_text("\n".join(site.getsitepackages()) + "\n")
    run(python, "-m", "pip", "install", "--quiet", "--no-deps", "--ignore-installed", REPO, cwd=tmp_path)
    elsewhere = tmp_path / "elsewhere"
    elsewhere.mkdir()
    environment = {key: value for key, value in os.environ.items() if key != "PYTHONPATH"}
    located = run(
        python, "-c", "import besman.robots as r; print(r.__file__)", cwd=elsewhere, env=environment
    )
    assert Path(located.stdout.strip()).is_relative_to(venv), "besman came from the wheel, not the checkout"
    shown = run(venv / "bin" / "besman", "robots", "show", "aila", "--json", cwd=elsewhere, env=environment)
    assert '"J_Shoulder1_r"' in shown.stdout
