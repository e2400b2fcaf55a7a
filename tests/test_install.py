"""The package as a user installs it, and the README as a newcomer follows it.

The wheel and the source distribution build and pass ``twine check``; the wheel, installed into a fresh
virtual environment, runs from an empty folder (package data, no source checkout), and there every command of
the README runs in the order it is written: its set-up commands are the ones CI runs, its tour's commands
succeed (the ones that serve the browser viewer answer it and end on Ctrl-C), its files are written where it
says and its Python runs.
"""

import json
import os
import re
import shlex
import shutil
import site
import subprocess
import sys
from concurrent.futures import ThreadPoolExecutor
from pathlib import Path

import pytest
from helpers import serve_then_interrupt

REPO = Path(__file__).resolve().parents[1]
README = REPO / "README.md"
APT = "apt-get update && apt-get install -y --no-install-recommends"


def run(*argv, **options) -> subprocess.CompletedProcess:
    """A command that must succeed; its stderr is part of the failure message."""
    result = subprocess.run([str(a) for a in argv], capture_output=True, text=True, **options)
    assert result.returncode == 0, f"{' '.join(map(str, argv))} failed:\n{result.stderr[-3000:]}"
    return result


class Installed:
    """The wheel installed into a fresh virtual environment (its `besman` first on the PATH)."""

    def __init__(self, root: Path) -> None:
        # Built from a copy of the sources (building writes into the source folder).
        source = root / "source"
        shutil.copytree(
            REPO,
            source,
            ignore=shutil.ignore_patterns(
                ".git", "build", "dist", "site", "*.egg-info", "__pycache__", ".*cache"
            ),
        )
        dist = root / "dist"
        run(sys.executable, "-m", "build", "--sdist", "--wheel", "--outdir", dist, source)  # as pip builds
        (self.wheel,) = dist.glob("besman-*.whl")
        (self.sdist,) = dist.glob("besman-*.tar.gz")
        self.venv = root / "venv"
        # The venv sees the already-installed dependencies (no downloads) but gets its own copy of besman.
        # --system-site-packages shows the base interpreter's packages; inside a virtual environment the
        # dependencies live in that environment instead, so its site-packages are added by a .pth file
        # (plain paths: the editable besman's own .pth hooks there are not run).
        run(sys.executable, "-m", "venv", "--system-site-packages", self.venv)
        self.python = self.venv / "bin" / "python"
        if sys.prefix != sys.base_prefix:
            purelib = run(
                self.python, "-c", "import sysconfig; print(sysconfig.get_paths()['purelib'])"
            ).stdout.strip()
            Path(purelib, "outer_environment.pth").write_text("\n".join(site.getsitepackages()) + "\n")
        pip = (self.python, "-m", "pip", "install", "-q", "--no-deps", "--ignore-installed")
        run(*pip, self.wheel, cwd=root)
        self.environment = {key: value for key, value in os.environ.items() if key != "PYTHONPATH"}
        self.environment["PATH"] = f"{self.venv / 'bin'}{os.pathsep}{os.environ['PATH']}"

    def besman(self, *argv, cwd: Path) -> str:
        return run(self.venv / "bin" / "besman", *argv, cwd=cwd, env=self.environment).stdout


@pytest.fixture(scope="module")
def installed(tmp_path_factory) -> Installed:
    return Installed(tmp_path_factory.mktemp("install"))


@pytest.mark.slow
def test_the_wheel_and_sdist_pass_twine_and_the_installed_wheel_runs_from_an_empty_folder(
    installed, tmp_path
):
    result = run(sys.executable, "-m", "twine", "check", "--strict", installed.wheel, installed.sdist)
    assert "PASSED" in result.stdout
    located = run(
        installed.python,
        "-c",
        "import besman.robots as r; print(r.__file__)",
        cwd=tmp_path,
        env=installed.environment,
    )
    assert Path(located.stdout.strip()).is_relative_to(installed.venv), "besman came from the checkout"
    assert installed.besman("--version", cwd=tmp_path).startswith("besman ")
    assert '"J_Shoulder1_r"' in installed.besman("robots", "show", "aila", "--json", cwd=tmp_path)
    result = json.loads(installed.besman("demo", "--json", cwd=tmp_path))
    assert result["status"] == "SUCCESS" and result["success"] is True
    assert Path(installed.besman("examples", "--copy", ".", cwd=tmp_path).strip()) == Path("examples")
    trees = sorted(str(p.relative_to(tmp_path)) for p in (tmp_path / "examples" / "trees").glob("*.yaml"))
    assert [Path(tree).name for tree in trees] == sorted(
        p.name for p in (REPO / "examples" / "trees").glob("*.yaml")
    )
    installed.besman("tree", "check", *trees, cwd=tmp_path)

    # The robots docs/robots.md runs by their folders, brought from a package's files.
    def files(folder: Path) -> list[str]:
        found = (p.relative_to(folder) for p in folder.rglob("*") if p.is_file())
        return sorted(str(p) for p in found if "__pycache__" not in p.parts)

    assert files(tmp_path / "examples" / "robots") == files(REPO / "examples" / "robots")
    robots = sorted(p.name for p in (tmp_path / "examples" / "robots").iterdir())
    for robot in robots:
        shown = installed.besman("robots", "show", f"examples/robots/{robot}", "--json", cwd=tmp_path)
        assert json.loads(shown)["name"] == robot


@pytest.mark.slow
def test_every_shipped_tree_runs_from_the_installed_wheel_on_every_robot_its_task_fits(installed, tmp_path):
    """``besman run examples/trees/NAME.yaml [--robot R]`` succeeds for every shipped tree file, on its task's
    default robot and on every other robot the task fits, from an empty folder with the examples copied out
    of the installed wheel (two runs at a time)."""
    import besman.robots as robots
    from besman.tasks import task
    from besman.trees.files import tree_task

    installed.besman("examples", "--copy", ".", cwd=tmp_path)
    runs = [
        (str(path.relative_to(tmp_path)), robot)
        for path in sorted((tmp_path / "examples" / "trees").glob("*.yaml"))
        for robot in robots.available()
        if task(tree_task(path)).fits(robots.describe(robot))
    ]
    shipped = {str(path.relative_to(tmp_path)) for path in (tmp_path / "examples" / "trees").glob("*.yaml")}
    assert {tree for tree, _ in runs} == shipped and len(runs) >= 2 * len(shipped)

    def run_tree(tree_and_robot):
        tree, robot = tree_and_robot
        argv = [installed.venv / "bin" / "besman", "run", tree, "--robot", robot, "--json"]
        result = subprocess.run(argv, capture_output=True, text=True, cwd=tmp_path, env=installed.environment)
        summary = json.loads(result.stdout) if result.stdout.startswith("{") else {}
        return tree, robot, result.returncode, summary.get("outcome", result.stderr[-300:])

    with ThreadPoolExecutor(2) as pool:
        failed = [run for run in pool.map(run_tree, runs) if run[2] != 0]
    assert failed == []


def readme_blocks() -> list[tuple[str, str, str | None, str]]:
    """The README's fenced blocks in order: (section, language, the file it is to be saved as, text)."""
    text = README.read_text()
    blocks = []
    pattern = r"(?:<!-- file: (\S+) -->\n)?```(\w*)\n(.*?)```"
    for match in re.finditer(pattern, text, flags=re.DOTALL):
        sections = re.findall(r"^## (.+)$", text[: match.start()], flags=re.MULTILINE)
        blocks.append((sections[-1] if sections else "", match.group(2), match.group(1), match.group(3)))
    return blocks


def commands(block: str) -> list[list[str]]:
    """A bash block's commands, one per line, without their comments."""
    return [shlex.split(line, comments=True) for line in block.splitlines() if line.strip()]


def test_the_readme_set_up_commands_are_the_main_job_and_what_ci_runs():
    """The two set-up commands: the main job (system libraries, the package, the default demo) and the
    test command, which is what ``.ci/run`` runs and installs everything the main job does."""
    setup = [text.strip() for section, language, _, text in readme_blocks() if section == "Set up"]
    assert len(setup) == 2
    main_job, test_command = setup
    assert main_job.startswith(APT) and main_job.endswith("&& pip install -e . && besman demo")
    assert run(REPO / ".ci" / "run", "--print").stdout.strip() == test_command
    packages = main_job.removeprefix(APT).split("&&")[0].split()
    assert set(packages) <= set(test_command.removeprefix(APT).split("&&")[0].split())
    installs = 'pip install -e ".[dev,distributed,datasets,gym]"'
    assert test_command.endswith(f"&& {installs} && python tests/suite.py")


@pytest.mark.slow
def test_every_command_of_the_readme_runs_in_order_from_an_empty_folder(installed, tmp_path):
    blocks = readme_blocks()
    kinds = {(section, language) for section, language, _, _ in blocks}
    assert kinds == {
        ("Set up", "bash"),
        ("A five-minute tour", "bash"),
        ("A five-minute tour", "yaml"),
        ("A five-minute tour", "python"),
        ("How it fits together", ""),  # the sketch
    }, "a block the test does not know how to run"
    folder = tmp_path
    installed.besman("demo", cwd=folder)  # the main job's own command
    ran = []
    for section, language, file, text in blocks:
        if section != "A five-minute tour":
            continue
        if file is not None:
            (folder / file).write_text(text)
            continue
        if language == "python":
            run(installed.python, "-c", text, cwd=folder, env=installed.environment)
            ran.append("python")
            continue
        for argv in commands(text):
            assert argv[0] == "besman", argv
            if "--view" in argv or argv[1] == "view":
                serve_then_interrupt(
                    [installed.venv / "bin" / "besman", *argv[1:]], cwd=folder, env=installed.environment
                )
            else:
                installed.besman(*argv[1:], cwd=folder)
            ran.append(shlex.join(argv))
    assert len(ran) >= 15, ran
    # What the tour says it leaves behind.
    assert (folder / "segments.png").read_bytes()[:4] == b"\x89PNG"
    assert {"reach.json", "carry.json", "return.json"} <= {p.name for p in (folder / "mypool").iterdir()}
    assert (folder / "throwing" / "results.json").is_file() and (folder / "run.jsonl").is_file()
