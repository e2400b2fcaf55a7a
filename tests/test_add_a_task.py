"""The documentation's "Add a task" page (docs/tasks.md), followed literally: its files written as it says,
its package installed, its commands run, its test passed; and the registry's rules for task modules."""

from pathlib import Path

import pytest
from helpers import follow_page

from besman.tasks import TASKS, task, task_names

ROOT = Path(__file__).resolve().parents[1]
PAGE = ROOT / "docs" / "tasks.md"


@pytest.mark.slow
def test_the_add_a_task_page_works_as_written(tmp_path):
    outputs = follow_page(PAGE, tmp_path / "besman-tidy")
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
