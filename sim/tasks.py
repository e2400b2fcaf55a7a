"""The task registry: every simulated task by name, what it needs of a robot, its tau box and how it is
built - the one place the command line, the experiments, learning and the trees find tasks.

A :class:`TaskKind` says what a task is independently of the robot it runs on: a name, one line on what it
does and what counts as success, which robots it fits (from their descriptions), the robot it runs on by
default, and - for a robot - its box of task parameters tau and the task object itself, a
:class:`~besman.sim.evaluation.BatchedTask` (``bounds``, the one batched ``evaluate(thetas, taus)``, and
``episode``). Pick and place takes its box from the robot's tabletop layout,
so it has one box per robot; the throwing tasks belong to the PA-10.

Adding a task is adding one entry to :data:`TASKS`.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass
from typing import Any

import besman.robots as robots
from besman.robots import RobotDescription
from besman.skills.errors import UnknownNameError
from besman.skills.tasks import TaskBounds


@dataclass(frozen=True)
class TaskKind:
    """A task of the registry; see the module documentation."""

    name: str
    title: str
    success: str
    robot: str
    fits: Callable[[RobotDescription], bool]
    bounds: Callable[[str], TaskBounds]
    build: Callable[[str], Any]

    def check_robot(self, robot: str | None) -> str:
        """``robot`` (default: the task's own) if the task fits it; otherwise an error naming the robots
        that fit."""
        return robots.choose(robot, self.robot, self.fits, f"task {self.name}")

    def describe(self, robot: str | None = None) -> dict:
        """The task on ``robot`` as JSON-ready facts: name, robot, what it does, success, tau's box and (for
        a tabletop task) the layout in the robot's frame."""
        robot = self.check_robot(robot)
        facts = {
            "task": self.name,
            "robot": robots.describe(robot).name,
            "title": self.title,
            "success": self.success,
            "bounds": self.bounds(robot).as_dict(),
        }
        layout = robots.describe(robot).tabletop
        if layout is not None and self.name == "pick-place":
            facts["layout"] = {
                "table": {
                    "height": layout.table.height,
                    "x": list(layout.table.x),
                    "y": list(layout.table.y),
                },
                "shelf": {
                    "height": layout.shelf.height,
                    "x": list(layout.shelf.x),
                    "y": list(layout.shelf.y),
                },
                "objects": {"x": list(layout.objects[0]), "y": list(layout.objects[1])},
                "places": {"x": list(layout.places[0]), "y": list(layout.places[1])},
            }
        return facts


def one_hand_tabletop(robot: RobotDescription) -> bool:
    """A tabletop layout and a first arm with a gripper: what pick and place needs."""
    arms = list(robot.arms.values())
    return robot.tabletop is not None and bool(arms) and arms[0].gripper is not None


def _pick_place_bounds(robot: str) -> TaskBounds:
    from besman.sim.pick_place import pick_place_bounds

    return pick_place_bounds(robot)


def _pick_place(robot: str):
    from besman.sim.pick_place import PickPlaceConfig, PickPlaceTask

    return PickPlaceTask(PickPlaceConfig(robot=robot))


def _throwing(variant: str) -> tuple[Callable[[str], TaskBounds], Callable[[str], Any]]:
    def bounds(robot: str) -> TaskBounds:
        from besman.sim.throwing import HARDWARE_BOUNDS, PAPER_BOUNDS

        return PAPER_BOUNDS if variant == "paper" else HARDWARE_BOUNDS

    def build(robot: str):
        from besman.sim.throwing import ThrowingTask

        return ThrowingTask(variant=variant)

    return bounds, build


def _pa10(robot: RobotDescription) -> bool:
    return robot.name == "pa10"


TASKS: dict[str, TaskKind] = {
    kind.name: kind
    for kind in (
        TaskKind(
            "pick-place",
            "pick a box from the table and place it on the shelf; tau = object x, y and place x, y (m)",
            "the box lifted, carried without a drop, then upright on the shelf within 2 cm of the target",
            "aila",
            one_hand_tabletop,
            _pick_place_bounds,
            _pick_place,
        ),
        TaskKind(
            "throwing",
            "the PA-10 throws a ball at a floor target (the paper's experiment); tau = target x, y (m)",
            "the landing's distance to the target (a throw that fails costs a penalty)",
            "pa10",
            _pa10,
            *_throwing("paper"),
        ),
        TaskKind(
            "throwing-hardware",
            "the PA-10 throws within its published speed limits at near targets; tau = target x, y (m)",
            "the landing's distance to the target (a throw that fails costs a penalty)",
            "pa10",
            _pa10,
            *_throwing("hardware"),
        ),
    )
}


def task_kind(name: str) -> TaskKind:
    """The registry's task ``name``; an unknown name lists the tasks."""
    if name not in TASKS:
        raise UnknownNameError(f"unknown task {name!r}; tasks: {', '.join(TASKS)}")
    return TASKS[name]
