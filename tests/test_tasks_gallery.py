"""The gallery's demos as tasks: sort, handover and throwing run through besman.tasks.running, judged by
their own rules; bad values and robots are refused by name before any work."""

import json

import numpy as np
import pytest

import besman.robots as robots
from besman.core.errors import InputError
from besman.robots.description import DescriptionError
from besman.tasks import task
from besman.tasks.handover import HANDOVER
from besman.tasks.running import prepare, run_demo
from besman.tasks.sort import places
from besman.tasks.throwing.rollouts import HARDWARE_BOUNDS

OPENARM = robots.describe("openarm").file


def test_sort_puts_every_box_in_its_place_though_one_slips():
    summary = run_demo("sort", 3)
    assert summary.success, summary.message
    measured = summary.measurements
    assert measured["slipped"] in places("aila") and max(measured["placement_errors_m"].values()) <= 0.02


def test_sort_without_a_seed_is_seed_zeros_configuration():
    unseeded, seeded = prepare("sort").runner.run_info, prepare("sort", seed=0).runner.run_info
    assert unseeded["settings"] == seeded["settings"]


@pytest.mark.parametrize("robot", ["aila", "openarm"])
def test_handover_places_the_bar_without_the_arms_touching(robot):
    summary = run_demo("handover", 0, robot=robot)
    assert summary.success, summary.message
    assert (
        summary.measurements["ticks_arms_touching"] == 0 and summary.measurements["placement_error_m"] <= 0.02
    )


def test_throwing_lands_near_the_target_it_is_given():
    summary = run_demo("throw", values={"target": (-2.5, -3.0)})
    assert summary.success and summary.demo == "throwing", summary.message
    assert summary.measurements["target"] == [-2.5, -3.0] and summary.measurements["miss_m"] <= 0.5


def test_throwing_hardware_throws_in_the_hardware_variants_world():
    found = task("throwing-hardware")
    assert found.bounds("pa10").low == HARDWARE_BOUNDS.low and found.batched("pa10").bounds == HARDWARE_BOUNDS
    scene = found.scene("pa10", found.resolve("pa10", {}, 1), 1)
    assert scene.executor.task.bounds == HARDWARE_BOUNDS and scene.judge().measurements["landing"] is None
    with pytest.raises(InputError, match="task throwing-hardware has no default tree"):
        prepare(found)


@pytest.mark.parametrize(
    ("name", "options", "message"),
    [
        (
            "handover",
            {"values": {"weight": (1.0,)}},
            "--set weight: not a value of task handover; its values: bar, place",
        ),
        ("throwing", {"values": {"target": (0.0, 0.0)}}, "tau target_x = 0 is outside the task's bounds"),
        ("sort", {"values": {"red": (0.7, -0.1)}}, "tau red_x = 0.7 is outside the task's bounds"),
        ("sort", {"values": {"red": (0.5, -0.1), "green": (0.55, -0.1)}, "seed": 1}, "red and green boxes"),
        ("handover", {"robot": "ur5e"}, "task handover does not run on 'ur5e'; it runs on: aila, openarm"),
        ("sort", {"robot": "pa10"}, "task sort does not run on 'pa10'"),
        ("throwing", {"robot": "aila"}, "task throwing does not run on 'aila'; it runs on: pa10"),
    ],
)
def test_bad_values_and_robots_are_refused_by_name_before_any_work(monkeypatch, name, options, message):
    def no_work(*_):
        raise AssertionError("the scene was built")

    monkeypatch.setattr(type(task(name)), "scene", no_work)
    with pytest.raises(InputError, match=message.replace("(", r"\(").replace("[", r"\[")):
        prepare(name, **options)


def _robot(folder, name, handover):
    """A copy of the OpenArm's description, called ``name``, with ``handover`` as its tasks.handover."""
    folder.mkdir()
    description = {**json.loads(OPENARM.read_text()), "name": name, "tasks": {"handover": handover}}
    (folder / "description.json").write_text(json.dumps(description))
    return str(folder)


def test_a_robot_the_task_does_not_know_brings_its_handover_in_its_description(tmp_path):
    openarm = HANDOVER["openarm"]
    handover = {
        "bar": {"x": [0.2, 0.24], "y": [0.1, 0.14]},
        "places": {"x": list(openarm.places[0]), "y": list(openarm.places[1])},
        "ready": openarm.ready,
        "present": {"position": [0.25, 0.06, 0.95], "yaw": 0.1},
    }
    robot = _robot(tmp_path / "mine", "mine", handover)
    found = task("handover")
    assert found.check_robot(robot) == robot
    bounds = found.bounds(robot).as_dict()
    assert bounds["bar_x"] == [0.2, 0.24] and bounds["bar_y"] == [0.1, 0.14]
    assert found.numbers(robot).present == {"position": (0.25, 0.06, 0.95), "yaw": 0.1}
    values = found.resolve(robot, {}, 7)
    assert 0.2 <= values["bar"][0] <= 0.24 and np.all(np.isfinite(values["place"]))
    off_the_shelf = {**handover, "places": {"x": [0.2, 0.24], "y": [0.1, 0.14]}}
    with pytest.raises(DescriptionError, match=r"tasks\.handover\.places: the area .* must lie on the board"):
        found.bounds(_robot(tmp_path / "off", "off", off_the_shelf))
    without_present = {key: value for key, value in handover.items() if key != "present"}
    with pytest.raises(DescriptionError, match="present"):
        found.bounds(_robot(tmp_path / "short", "short", without_present))
    # Where each hand holds the bar: the task's 8 cm from its middle, or the robot's own (wide wrists).
    assert found.numbers(robot).grip == 0.08
    assert found.numbers(_robot(tmp_path / "wide", "wide", {**handover, "grip": 0.1})).grip == 0.1
    for grip in (0.2, "far", True):
        with pytest.raises(DescriptionError, match=r"tasks\.handover\.grip: how far from the bar's middle"):
            found.bounds(_robot(tmp_path / f"grip{grip}", "g", {**handover, "grip": grip}))
