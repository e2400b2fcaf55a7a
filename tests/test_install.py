"""The package as a user installs it: the wheel and the source distribution build and pass `twine check`, and
the wheel, installed into a fresh virtual environment, runs the README's commands from an empty folder - the
demos, the shipped trees and the shipped pool included (package data, no source checkout)."""

import json
import os
import shutil
import site
import subprocess
import sys
from pathlib import Path

import pytest

REPO = Path(__file__).resolve().parents[1]


def run(*argv, **options) -> subprocess.CompletedProcess:
    """A command that must succeed; its stderr is part of the failure message."""
    result = subprocess.run([str(a) for a in argv], capture_output=True, text=True, **options)
    assert result.returncode == 0, f"{' '.join(map(str, argv))} failed:\n{result.stderr[-3000:]}"
    return result


@pytest.mark.slow
def test_the_wheel_installed_into_a_fresh_venv_runs_the_readme_from_an_empty_folder(tmp_path):
    # Built from a copy of the sources (building writes into the source folder).
    source = tmp_path / "source"
    shutil.copytree(
        REPO,
        source,
        ignore=shutil.ignore_patterns(
            ".git", "build", "dist", "*.egg-info", "__pycache__", ".*cache", ".lock"
        ),
    )
    dist = tmp_path / "dist"
    run(sys.executable, "-m", "build", "--sdist", "--wheel", "--outdir", dist, source)  # as pip builds it
    (wheel,) = dist.glob("besman-*.whl")
    (sdist,) = dist.glob("besman-*.tar.gz")
    assert "PASSED" in run(sys.executable, "-m", "twine", "check", "--strict", wheel, sdist).stdout
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
    run(python, "-m", "pip", "install", "--quiet", "--no-deps", "--ignore-installed", wheel, cwd=tmp_path)
    empty = tmp_path / "empty"
    empty.mkdir()
    environment = {key: value for key, value in os.environ.items() if key != "PYTHONPATH"}
    besman = venv / "bin" / "besman"

    def command(*argv) -> str:
        return run(besman, *argv, cwd=empty, env=environment).stdout

    located = run(python, "-c", "import besman.robots as r; print(r.__file__)", cwd=empty, env=environment)
    assert Path(located.stdout.strip()).is_relative_to(venv), "besman came from the wheel, not the checkout"
    assert command("--version").startswith("besman ")
    assert '"J_Shoulder1_r"' in command("robots", "show", "aila", "--json")
    assert "grasp-then-place" in command("demo", "--list")
    result = json.loads(command("demo", "--json"))
    assert result["status"] == "SUCCESS" and result["success"] is True
    assert Path(command("examples", "--copy", ".").strip()) == Path("examples")
    trees = sorted(str(p.relative_to(empty)) for p in (empty / "examples" / "trees").glob("*.yaml"))
    assert len(trees) == 7
    command("tree", "check", *trees)
    learned = json.loads(
        command(
            "run",
            "examples/trees/grasp_then_place_learned.yaml",
            "--pool",
            "examples/pools/pick_place",
            "--set",
            "object=0.5,-0.05",
            "--set",
            "place=0.58,-0.44",
            "--json",
        )
    )
    assert learned["status"] == "SUCCESS", learned
