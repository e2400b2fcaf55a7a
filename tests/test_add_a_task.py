"""The documentation's "Add a task" page (docs/tasks.md), followed literally: its files written as it says,
its package installed, its commands run, its test passed; and the registry's rules for task modules."""

import os
import re
import shlex
import subprocess
import sys
from pathlib import Path

import pytest

from besman.tasks import TASKS, task, task_names

ROOT = Path(__file__).resolve().parents[1]
PAGE = ROOT / "docs" / "tasks.md"


def page_files() -> dict[str, str]:
    """The page's files: each block marked ``<!-- file: PATH -->``, by path."""
    pattern = r"<!-- file: (\S+) -->\n```\w*\n(.*?)```"
    return dict(re.findall(pattern, PAGE.read_text(), flags=re.DOTALL))


def page_commands() -> list[list[str]]:
    """The commands of the page's last bash block (its "Use it" section)."""
    block = re.findall(r"```bash\n(.*?)```", PAGE.read_text(), flags=re.DOTALL)[-1]
    return [shlex.split(line) for line in block.splitlines() if line.strip()]


def run(*argv, **options) -> subprocess.CompletedProcess:
    result = subprocess.run([str(a) for a in argv], capture_output=True, text=True, **options)
    assert result.returncode == 0, f"{' '.join(map(str, argv))} failed:\n{result.stdout}\n{result.stderr}"
    return result


@pytest.mark.slow
def test_the_add_a_task_page_works_as_written(tmp_path):
    package = tmp_path / "besman-tidy"
    for path, text in page_files().items():
        (package / path).parent.mkdir(parents=True, exist_ok=True)
        (package / path).write_text(text)
    site = tmp_path / "site"
    commands = page_commands()
    assert commands[0] == ["pip", "install", "./besman-tidy"]
    # The page's install, into a folder of its own (its build requirements installed as pip does).
    run(sys.executable, "-m", "pip", "install", "-q", "--no-deps", "--target", site, package)
    environment = {**os.environ, "PYTHONPATH": str(site)}
    outputs = []
    for command in commands[1:]:
        if command[0] == "besman":
            command = [Path(sys.executable).parent / "besman", *command[1:]]
        elif command[:3] == ["python", "-m", "pytest"]:
            command = [sys.executable, "-m", "pytest", "-q", "-p", "no:cacheprovider", *command[3:]]
        outputs.append(run(*command, cwd=package, env=environment).stdout)
    shown, demo, checked, tested = outputs
    assert "tidy on aila: put the box on the far right of the shelf" in shown
    assert "object_x\t[0.45, 0.62]" in shown
    assert "SUCCESS: placement error" in demo
    assert checked.strip().endswith("tidy.yaml: ok")
    assert "3 passed" in tested


def test_a_task_is_registered_by_its_module_and_named_by_its_aliases():
    assert task("throw") is TASKS["throwing"]
    assert task("grasp-then-place") is TASKS["pick-place"]
    assert set(task_names()) == {*TASKS, "throw", "grasp-then-place"}
    for entry in TASKS.values():  # what `besman tasks show` says of each: all of it given
        assert entry.title and entry.randomised and entry.success and entry.measurements
        assert entry.tree is None or entry.tree_path.is_file()


def test_the_tree_files_name_their_tasks_and_every_task_with_a_tree_is_a_demo():
    from besman.trees.files import tree_task

    shipped = {path.name: tree_task(path) for path in (ROOT / "examples" / "trees").glob("*.yaml")}
    assert all(shipped.values()), shipped
    assert {entry.tree for entry in TASKS.values() if entry.tree} <= set(shipped)
