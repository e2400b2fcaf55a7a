"""Running tree files: the command line, truthful summaries, logs that replay, the 40-configuration check."""

import json
import os
import shutil
from dataclasses import fields
from pathlib import Path

import numpy as np
import pytest

from besman.cli import main
from besman.tasks import TASKS, task
from besman.tasks.running import replay, run
from besman.trees.runner import read_log, statuses
from besman.trees.summary import RunSummary

PICK_PLACE = task("pick-place")
PICK_PLACE_BOUNDS = PICK_PLACE.bounds("aila")

TREE = Path(__file__).resolve().parents[1] / "examples" / "trees" / "grasp_then_place.yaml"


def test_run_prints_a_truthful_json_summary(capsys, tmp_path):
    log = tmp_path / "run.jsonl"
    code = main(
        [
            "run",
            str(TREE),
            "--set",
            "object=0.55,-0.10,30",
            "--set",
            "place=0.50,-0.40,0",
            "--json",
            "--log",
            str(log),
        ]
    )
    summary = json.loads(capsys.readouterr().out)
    assert code == 0
    # The one documented shape of every run's and demo's --json (besman.trees.summary).
    assert list(summary) == ["schema_version", "kind", *(item.name for item in fields(RunSummary))]
    assert summary["schema_version"] == 3 and summary["kind"] == "besman-run-summary"
    assert set(summary["measurements"]) == set(PICK_PLACE.measurements) and summary["demo"] is None
    assert summary["task"] == "pick-place"  # the task the file names
    assert summary["tree"] == str(TREE.resolve()) and summary["robot"] == "aila"
    assert summary["status"] == "SUCCESS" and summary["failed_node"] is None
    header, records, result = read_log(log)
    assert header["run"]["settings"] == {
        "object": [0.55, -0.10, 30.0],
        "place": [0.50, -0.40, 0.0],
        "shape": [0.0],
        "size": [0.06, 0.06, 0.06],
    }
    assert header["run"]["task"] == "pick-place" and header["run"]["values"] == header["run"]["settings"]
    final_box = np.array(records[-1]["robot"]["objects"]["box"])
    assert summary["measurements"]["placement_error_m"] == pytest.approx(
        np.linalg.norm(final_box[:2] - [0.50, -0.40]), abs=1e-4
    )
    assert summary["measurements"]["placement_error_m"] < 0.02 and summary["success"]
    assert result["ticks"] == summary["ticks"] == len(records)
    assert records[-1]["time"] == pytest.approx(summary["sim_time_s"], abs=0.02)
    writes = [change["key"] for record in records for change in record["blackboard"]]
    assert "/grasp/reach" in writes and "/place/carry" in writes


@pytest.mark.slow
def test_the_log_replays_to_the_same_statuses(tmp_path):
    log = tmp_path / "run.jsonl"
    run(
        tree=TREE,
        values={"object": (0.5, -0.05, 30.0), "place": (0.58, -0.44, 0.0), "shape": "cylinder"},
        log=log,
    )
    _, records, _ = read_log(log)
    assert replay(log) == list(statuses(records))


def test_values_outside_the_bounds_are_rejected(capsys):
    code = main(["run", str(TREE), "--set", "object=0.55,-0.20,0", "--set", "place=0.40,0.25,0"])
    assert code == 2
    assert "tau object_y = -0.2 is outside the task's bounds [-0.15, 0]" in capsys.readouterr().err
    assert main(["run", str(TREE), "--set", "object=0.55,-0.1,270"]) == 2
    assert "tau object_yaw = 270 is outside the task's bounds [-180, 180]" in capsys.readouterr().err
    assert main(["run", str(TREE), "--set", "object=near"]) == 2
    err = capsys.readouterr().err
    assert "--set object: takes numbers (object_x, object_y, object_yaw), got 'near'" in err
    assert main(["run", str(TREE), "--set", "object=0.55,-0.1"]) == 2
    assert "--set object needs 3 number(s) (object_x, object_y, object_yaw), got 2" in capsys.readouterr().err


def columns(shown: dict) -> dict:
    """``besman tasks show --json``'s tau columns, by name: (unit, range)."""
    return {column["name"]: (column["unit"], column["range"]) for column in shown["tau"]}


def test_tasks_show_prints_the_bounds(capsys):
    assert main(["tasks", "show", "pick-place", "--json"]) == 0
    shown = json.loads(capsys.readouterr().out)
    assert [column["name"] for column in shown["tau"]] == list(PICK_PLACE.names)
    assert {name: span for name, (_, span) in columns(shown).items()} == PICK_PLACE_BOUNDS.as_dict()
    assert shown["values"]["object"]["units"] == ["m", "m", "deg"]
    assert main(["tasks", "show", "throwing", "--json"]) == 0
    shown = json.loads(capsys.readouterr().out)
    throwing = task("throwing").bounds("pa10").as_dict()
    assert {name: span for name, (_, span) in columns(shown).items()} == throwing
    # the target's x and y on the floor
    assert columns(shown) == {"target_x": ("m", [-7.0, -1.0]), "target_y": ("m", [-5.0, 1.0])}
    assert main(["tasks", "show", "juggling"]) == 2
    unknown = f"unknown task 'juggling'; tasks: {', '.join(TASKS)}"
    assert unknown in capsys.readouterr().err and "pick-place, pick, place" in unknown
    assert main(["tasks"]) == 0
    assert [line.split("\t")[0] for line in capsys.readouterr().out.splitlines()] == list(TASKS)
    assert main(["tasks", "show", "pick-place"]) == 0
    lines = capsys.readouterr().out.splitlines()
    assert f"randomised: {PICK_PLACE.randomised}" in lines and f"success: {PICK_PLACE.success}" in lines
    assert "default tree: grasp_then_place.yaml" in lines and "place_y\t[-0.48, -0.34] m" in lines
    assert "place_yaw\t[-180, 180] deg" in lines and "shape\t[0, 1]: 0 = box, 1 = cylinder" in lines
    assert "objects: box or cylinder, width 0.04-0.07 m, height 0.05-0.08 m" in "\n".join(lines)
    assert main(["tasks", "show", "throwing", "--robot", "ur5e"]) == 2
    assert "task throwing does not run on 'ur5e'; it runs on: pa10" in capsys.readouterr().err


def test_tree_show_and_render(capsys, tmp_path):
    assert main(["tree", "show", str(TREE)]) == 0
    assert "grasp then place" in capsys.readouterr().out
    if shutil.which("dot") is None and not os.environ.get("CI"):
        pytest.skip("Graphviz is not installed here (CI installs it and must not skip)")
    out = tmp_path / "tree.svg"
    assert main(["tree", "render", str(TREE), "--out", str(out)]) == 0
    assert out.read_text().lstrip().startswith(("<?xml", "<svg"))
    assert "grasp then place" in out.read_text()


def test_seeded_settings_are_reproducible_and_in_bounds():
    first = PICK_PLACE.resolve("aila", {}, seed=4)
    tau = PICK_PLACE.join(first)
    np.testing.assert_array_equal(tau, PICK_PLACE.join(PICK_PLACE.resolve("aila", {}, seed=4)))
    PICK_PLACE_BOUNDS.check(tau)
    assert not np.array_equal(tau, PICK_PLACE.join(PICK_PLACE.resolve("aila", {}, seed=5)))


def test_without_a_seed_a_run_takes_the_tasks_default_configuration():
    """No longer drawn: AILA's documented configuration, other robots the middle of their areas."""
    values = PICK_PLACE.resolve("aila", {}, None)
    box = [0.0, 0.06, 0.06, 0.06]  # the 6 cm box
    assert PICK_PLACE.join(values).tolist() == [0.55, -0.08, 0.0, 0.54, -0.41, 0.0, *box]
    ur5e = PICK_PLACE.bounds("ur5e").as_dict()
    middle = [sum(ur5e[name]) / 2 for name in ("object_x", "object_y", "place_x", "place_y")]
    expected = [*middle[:2], 0.0, *middle[2:], 0.0, *box]
    np.testing.assert_allclose(PICK_PLACE.join(PICK_PLACE.resolve("ur5e", {}, None)), expected)
    given = PICK_PLACE.resolve("aila", {"place": (0.5, -0.4, 90.0), "shape": "cylinder"}, None)
    assert PICK_PLACE.join(given).tolist() == [0.55, -0.08, 0.0, 0.5, -0.4, 90.0, 1.0, 0.06, 0.06, 0.06]


@pytest.mark.slow
def test_grasp_then_place_succeeds_in_40_random_configurations():
    """39 of 40 seeded configurations drawn from the task's bounds (any object and place yaw, boxes and
    cylinders of every size), with real contact grasps, succeed by the task's rule (the tree succeeds and the
    object stands upright on the shelf within 2 cm and 5 deg). Measured on 2026-11-26: 40 of 40 (seeds 24,
    25 and 28 failed before the grasp was chosen for a placement that plans from its lift and the reach kept
    its margin from the shelf); 237 of seeds 0-239."""
    summaries = [run(tree=TREE, seed=seed) for seed in range(40)]
    successes = [s for s in summaries if s.success]
    assert len(successes) >= 39, [(i, s.status, s.outcome) for i, s in enumerate(summaries) if not s.success]
    assert all(s.status == "SUCCESS" and s.measurements["placement_error_m"] < 0.02 for s in successes)
    assert all(s.measurements["tilt_deg"] < 10 for s in successes)


@pytest.mark.slow
def test_a_pool_given_on_the_command_line_is_named_in_the_summary(capsys):
    """``--pool`` replaces the pools the tree names: the summary's tree says so."""
    learned = TREE.with_name("grasp_then_place_learned.yaml")
    pool = (TREE.parents[1] / "pools" / "pick_place_aila").resolve()
    assert main(["run", str(learned), "--pool", str(pool), "--json"]) == 0
    summary = json.loads(capsys.readouterr().out)
    assert summary["success"] and summary["task"] == "pick-place"
    assert summary["tree"] == f"{learned.resolve()} (--pool {pool})"
