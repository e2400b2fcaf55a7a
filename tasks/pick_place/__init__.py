"""Pick and place: the robot takes a box from the table and puts it on the shelf with its first arm (AILA:
the right arm and the waist). Also its two halves as tasks of their own, ``pick`` and ``place``.

- **pick-place** (default tree ``grasp_then_place.yaml``; the demo's earlier name ``grasp-then-place``).
  Randomised: tau = object x, y (where the 6 cm box stands on the table: the area the robot's first arm
  reaches, its description's ``tabletop.reach``) and place x, y (its target on the shelf board:
  :data:`PLACES`), drawn uniformly. Success (:func:`~besman.tasks.pick_place.rule.placement`): after 0.3 s
  to settle, the box stands upright (tilt < 10 deg) on the shelf within 2 cm of the place target.
- **pick** (``grasp.yaml``): tau = object x, y. Success: the box is in the hand and 5 cm above where it
  stood (:func:`~besman.tasks.pick_place.rule.lifted`).
- **place** (``place.yaml``): tau = object x, y and place x, y; the run begins with the box in the hand, 5 cm
  above where it stood (grasped by the planned pick). Success as pick-place's.

Without a seed, AILA's run uses :data:`DEFAULT_CONFIGURATION` (the documentation's examples use it too) and
other robots the middle of their areas. Learning (``besman learn``) imitates and refines three building
blocks of the task, ``reach``, ``carry`` and ``return`` (:mod:`besman.tasks.pick_place.blocks`); policy
search tunes the scripted plan's numbers (:mod:`besman.tasks.pick_place.episode`).

Sim and tree modules are imported by the methods that need them, so that listing the tasks stays fast.
"""

from __future__ import annotations

from collections.abc import Mapping
from typing import ClassVar

import numpy as np

from besman.skills.errors import InputError
from besman.skills.tasks import TaskBounds
from besman.tasks.base import Scene, Task, TaskValue

# The place area on the shelf board per robot, x and y ranges (m): where its first arm reaches top-down
# placings and the poses above them (each robot's README says how it was found: AILA's is where the right
# arm, turning the waist, keeps every joint 5 % of its range from its limits for some yaw, on a grid).
PLACES = {
    "aila": ((0.45, 0.62), (-0.48, -0.34)),
    "ur5e": ((0.32, 0.49), (-0.45, -0.31)),
    "openarm": ((0.17, 0.30), (-0.42, -0.32)),
}
DEFAULT_CONFIGURATION = {"aila": {"object": (0.55, -0.08), "place": (0.54, -0.41)}}
OBJECT = TaskValue(
    "object", ("object_x", "object_y"), "m", "where the box stands on the table", surface="table"
)
PLACE = TaskValue(
    "place", ("place_x", "place_y"), "m", "where the box goes on the shelf", surface="shelf", target=True
)


def _read_places(section: dict, where: str, layout):
    from besman.robots.description import DescriptionError, read_area

    if "places" not in section:
        raise DescriptionError(f"{where}: missing 'places' (the place area on the shelf, x and y ranges)")
    return read_area(section["places"], f"{where}.places", None if layout is None else layout.shelf)


def areas(robot: str):
    """The object area (table) and the place area (shelf) on ``robot``, or None where it has no place area
    (not a robot of :data:`PLACES`, and no ``tasks.pick-place.places`` in its description)."""
    import besman.robots as robots

    layout = robots.describe(robot).tabletop
    places = PickPlace().robot_numbers(robot, PLACES, _read_places)
    if layout is None or places is None:
        return None
    return layout.reach, places


def one_hand_tabletop(robot) -> bool:
    """A work surface, a first arm with a gripper and a place area: what pick and place needs."""
    arms = list(robot.arms.values())
    return bool(arms) and arms[0].gripper is not None and areas(str(robot.folder)) is not None


class PickPlace(Task):
    name = "pick-place"
    aliases = ("grasp-then-place",)
    title = "pick the box from the table and place it on the shelf"
    randomised = "the box's position on the table and its target on the shelf (tau)"
    success = (
        "after settling 0.3 s the box stands upright (tilt < 10 deg) on the shelf within 2 cm of the target"
    )
    robot = "aila"
    tree = "grasp_then_place.yaml"
    values = (OBJECT, PLACE)
    measurements: ClassVar[Mapping[str, str]] = {
        "placement_error_m": "the box's distance from its target on the shelf, in the plane",
        "tilt_deg": "the box's tilt from upright",
        "box_position": "where the box ended, x, y, z in the world",
    }

    def fits(self, robot) -> bool:
        return one_hand_tabletop(robot)

    def bounds(self, robot: str) -> TaskBounds:
        found = areas(robot)
        if found is None:
            raise InputError(
                f"robot {robot!r} has no pick-and-place areas: task {self.name} does not run on it"
            )
        areas_in_order = {"object": found[0], "place": found[1]}
        names, low, high = [], [], []
        for value in self.values:
            (x0, x1), (y0, y1) = areas_in_order[value.name]
            names += value.names
            low += [x0, y0]
            high += [x1, y1]
        return TaskBounds(tuple(names), tuple(low), tuple(high))

    def default_values(self, robot: str) -> dict[str, np.ndarray]:
        import besman.robots as robots

        given = DEFAULT_CONFIGURATION.get(robots.describe(robot).name)
        if given is None:
            return super().default_values(robot)
        return {value.name: np.asarray(given[value.name], dtype=float) for value in self.values}

    def world(self, robot: str):
        from besman.sim.world import tabletop_world

        return tabletop_world(robot=robot)

    def scene(self, robot: str, values, seed: int | None) -> Scene:
        from besman.sim.executor import Executor

        world = self.world(robot)
        world.place_on("box", "table", *values["object"])
        executor = Executor(world)
        return Scene(executor, dict(values), _listed(values), lambda: self.judge(executor, values))

    def judge(self, executor, values):
        """The success rule on the executor's world as it stands (see the module documentation)."""
        from besman.tasks.pick_place.rule import measure_placement

        return measure_placement(executor.world, "box", values["place"])

    def batched(self, robot: str):
        from besman.tasks.pick_place.episode import PickPlaceConfig, PickPlaceTask

        return PickPlaceTask(PickPlaceConfig(robot=robot))

    def building_blocks(self, robot: str):
        from besman.tasks.pick_place.blocks import building_blocks

        return building_blocks(self, robot)

    def facts(self, robot: str) -> dict:
        objects, places = areas(robot)
        return {
            "areas": {
                "objects": {"x": list(objects[0]), "y": list(objects[1])},
                "places": {"x": list(places[0]), "y": list(places[1])},
            }
        }


class Pick(PickPlace):
    name = "pick"
    aliases = ()
    title = "pick the box from the table and lift it"
    randomised = "the box's position on the table (tau)"
    success = "the box is in the hand, 5 cm above where it stood"
    tree = "grasp.yaml"
    values = (OBJECT,)
    measurements: ClassVar[Mapping[str, str]] = {
        "lift_m": "how far above where it stood the box ended",
        "held": "whether the hand holds the box",
        "box_position": "where the box ended, x, y, z in the world",
    }

    def judge(self, executor, values):
        from besman.tasks.pick_place.rule import measure_lift

        return measure_lift(executor, "box")

    def batched(self, robot: str):
        return None

    def building_blocks(self, robot: str):
        return None


class Place(PickPlace):
    name = "place"
    aliases = ()
    title = "put the box, held in the hand above the table, on the shelf"
    randomised = "where the box was grasped on the table and its target on the shelf (tau)"
    tree = "place.yaml"

    def scene(self, robot: str, values, seed: int | None) -> Scene:
        from besman.tasks.pick_place.blocks import held_above_table

        executor = held_above_table(self.world(robot), values["object"], values["place"])
        return Scene(executor, dict(values), _listed(values), lambda: self.judge(executor, values))

    def batched(self, robot: str):
        return None

    def building_blocks(self, robot: str):
        return None


def _listed(values) -> dict:
    return {name: [round(float(v), 6) for v in value] for name, value in values.items()}


TASKS = (PickPlace(), Pick(), Place())
