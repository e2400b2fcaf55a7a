"""Pick and place: the robot takes a box from the table and puts it on the shelf with its first arm (AILA:
the right arm and the waist). Also its two halves as tasks of their own, ``pick`` and ``place``.

The object (the world's ``box``, whatever its shape) comes from :data:`FAMILY`: a box (width, depth, height)
or a cylinder (diameter, height), its width bounded by what the robot's first gripper holds
(:meth:`~besman.sim.objects.ObjectFamily.for_gripper`).

- **pick-place** (default tree ``grasp_then_place.yaml``; the demo's earlier name ``grasp-then-place``).
  Randomised: tau = ``object`` x, y, yaw (where the object stands on the table: the area the robot's first
  arm reaches, its description's ``tabletop.reach``; yaw in deg over the whole circle), ``place`` x, y, yaw
  (its target on the shelf board, :data:`PLACES`, and the yaw it should stand at), ``shape`` (box or
  cylinder) and ``size`` (width, depth, height: a cylinder's diameter is its width, its depth is set to
  it), drawn uniformly; the seed also draws the object's mass and friction from the family's ranges.
  Success (:func:`~besman.tasks.pick_place.rule.measure_placement`): after 0.3 s to settle, the object
  stands upright (tilt < 10 deg) on the shelf within 2 cm of the place target and within 5 deg of its yaw
  (modulo the object's symmetry: a box's 180 deg, a square box's 90, a cylinder any). Perturbed
  (``--perturb``, :data:`PERTURBATIONS`): the object's pose is perceived up to 1.5 cm and 5 deg off at
  every look, and with ``push`` it is pushed 1-3 cm half-way through the reach.
- **pick** (``grasp.yaml``): tau = object, shape and size. Success: the object is in the hand and 5 cm
  above where it stood (:func:`~besman.tasks.pick_place.rule.measure_lift`).
- **place** (``place.yaml``): tau as pick-place's; the run begins with the object in the hand, 5 cm above
  where it stood (grasped by the planned pick). Success as pick-place's.

Without a seed, AILA's run uses :data:`DEFAULT_CONFIGURATION` (the documentation's examples use it too) and
other robots the middle of their areas, each with the 6 cm box where it fits (:data:`DEFAULT_OBJECT`).
Learning (``besman learn``) imitates and refines three building blocks of the task, ``reach``, ``carry``
and ``return`` (:mod:`besman.tasks.pick_place.blocks`); policy search tunes the scripted plan's numbers
(:mod:`besman.tasks.pick_place.episode`).

Sim and tree modules are imported by the methods that need them, so that listing the tasks stays fast.
"""

from __future__ import annotations

from collections.abc import Mapping
from typing import ClassVar

import numpy as np

from besman.core.errors import InputError
from besman.sim.objects import GraspableObject
from besman.skills.task_bounds import TaskBounds
from besman.tasks.base import Scene, Task
from besman.tasks.pick_place.scene import (
    DEFAULT_CONFIGURATION,
    DEFAULT_OBJECT,
    FAMILY,
    OBJECT,
    PERTURBATIONS,
    PLACE,
    PLACES,
    PROPERTIES_STREAM,
    SHAPE,
    SIZE,
    YAWS,
    aperture,
    areas,
    check_holdable,
    family,
    first_hand,
    one_hand_tabletop,
    the_object,
)


class PickPlace(Task):
    name = "pick-place"
    aliases = ("grasp-then-place",)
    section = "places: the area on the shelf where the object goes"
    title = "pick the object from the table and place it on the shelf"
    randomised = (
        "the object's position and yaw on the table, its target position and yaw on the shelf, its shape and "
        "size (tau); its mass and friction (the seed)"
    )
    success = (
        "after settling 0.3 s the object stands upright (tilt < 10 deg) on the shelf within 2 cm of the "
        "target and 5 deg of its yaw (modulo the object's symmetry)"
    )
    robot = "aila"
    tree = "grasp_then_place.yaml"
    values = (OBJECT, PLACE, SHAPE, SIZE)
    perturbations = PERTURBATIONS
    measurements: ClassVar[Mapping[str, str]] = {
        "placement_error_m": "the object's distance from its target on the shelf, in the plane",
        "placement_yaw_error_deg": "how far the object's yaw is from the target's, modulo its symmetry",
        "tilt_deg": "the object's tilt from upright",
        "box_position": "where the object ended, x, y, z in the world",
    }

    def fits(self, robot) -> bool:
        return one_hand_tabletop(robot)

    def bounds(self, robot: str) -> TaskBounds:
        found = areas(robot)
        if found is None:
            raise InputError(
                f"robot {robot!r} has no pick-and-place areas: task {self.name} does not run on it"
            )
        objects = family(robot)
        ranges = {
            "object": (*found[0], YAWS),
            "place": (*found[1], YAWS),
            "shape": ((0, len(objects.shapes) - 1),),
            "size": (objects.width, objects.width, objects.height),
        }
        spans = [span for value in self.values for span in ranges[value.name]]
        low, high = zip(*spans, strict=True)
        names = self.names
        return TaskBounds(names, low, high)

    def default_values(self, robot: str) -> dict[str, np.ndarray]:
        import besman.robots as robots

        values = super().default_values(robot)
        given = {**DEFAULT_CONFIGURATION.get(robots.describe(robot).name, {}), **DEFAULT_OBJECT}
        for value in self.values:
            if value.name in given:
                values[value.name] = np.asarray(given[value.name], dtype=float)
        bounds = self.bounds(robot)
        return self.split(np.clip(self.join(values), bounds.low, bounds.high))

    def resolve(self, robot: str, given, seed: int | None) -> dict[str, np.ndarray]:
        """As :meth:`Task.resolve`; an object the robot's gripper cannot hold is refused with both widths,
        and a cylinder's depth is its diameter."""
        if "size" in given and "size" in {value.name for value in self.values}:
            check_holdable(robot, SIZE.numbers(given["size"]), SHAPE.numbers(given.get("shape", "box")))
        values = super().resolve(robot, given, seed)
        if "size" in values and FAMILY.shapes[int(values["shape"][0])] == "cylinder":
            values["size"] = np.array([values["size"][0], values["size"][0], values["size"][2]])
        return values

    def world(self, robot: str, item: GraspableObject):
        from besman.sim.world import tabletop_world

        return tabletop_world((item,), robot=robot)

    def scene(self, robot: str, values, seed: int | None) -> Scene:
        from besman.sim.executor import Executor

        world = self.world(robot, the_object(robot, values, seed))
        x, y, yaw = values["object"]
        world.place_on("box", "table", x, y, np.radians(yaw))
        executor = Executor(world)
        return Scene(executor, dict(values), _listed(values), lambda: self.judge(executor, values))

    def judge(self, executor, values):
        """The success rule on the executor's world as it stands (see the module documentation)."""
        from besman.tasks.pick_place.rule import measure_placement

        return measure_placement(executor.world, "box", values["place"])

    def batched(self, robot: str):
        from besman.tasks.pick_place.episode import PickPlaceConfig, PickPlaceRollouts

        return PickPlaceRollouts(PickPlaceConfig(robot=robot))

    def building_blocks(self, robot: str):
        from besman.tasks.pick_place.blocks import building_blocks

        return building_blocks(self, robot)

    def robot_checks(self, robot: str, description):
        """Its place area given, the first arm's home, its reach of the areas and one pick and place at
        their middles (:mod:`besman.tasks.pick_place.robot_checks`); pick and place, its halves, leave
        them to it."""
        if type(self) is not PickPlace:
            return
        from besman.tasks.pick_place.robot_checks import robot_checks

        yield from robot_checks(self, robot, description)

    def facts(self, robot: str) -> dict:
        objects, places = areas(robot)
        held = family(robot)
        return {
            "areas": {
                "objects": {"x": list(objects[0]), "y": list(objects[1])},
                "places": {"x": list(places[0]), "y": list(places[1])},
            },
            "objects": {
                "gripper_opening_m": round(aperture(robot), 4),
                "shapes": list(held.shapes),
                "width_m": list(held.width),
                "height_m": list(held.height),
                "mass_kg": list(held.mass),
                "friction": list(held.friction),
            },
        }


class Pick(PickPlace):
    name = "pick"
    aliases = ()
    section = ""
    title = "pick the object from the table and lift it"
    randomised = "the object's position and yaw on the table, its shape and size (tau); its mass and friction"
    success = "the object is in the hand, 5 cm above where it stood"
    tree = "grasp.yaml"
    values = (OBJECT, SHAPE, SIZE)
    measurements: ClassVar[Mapping[str, str]] = {
        "lift_m": "how far above where it stood the object ended",
        "held": "whether the hand holds the object",
        "box_position": "where the object ended, x, y, z in the world",
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
    section = ""
    title = "put the object, held in the hand above the table, on the shelf"
    randomised = (
        "where the object was grasped on the table, its target on the shelf, its shape and size (tau)"
    )
    tree = "place.yaml"

    def scene(self, robot: str, values, seed: int | None) -> Scene:
        from besman.tasks.pick_place.blocks import held_above_table

        executor = held_above_table(self.world(robot, the_object(robot, values, seed)), values)
        return Scene(executor, dict(values), _listed(values), lambda: self.judge(executor, values))

    def batched(self, robot: str):
        return None

    def building_blocks(self, robot: str):
        return None


def _listed(values) -> dict:
    return {name: [round(float(v), 6) for v in value] for name, value in values.items()}


TASKS = (PickPlace(), Pick(), Place())
# The scene's names stay importable from here, where they were first.
__all__ = [
    "DEFAULT_CONFIGURATION",
    "DEFAULT_OBJECT",
    "FAMILY",
    "OBJECT",
    "PERTURBATIONS",
    "PLACE",
    "PLACES",
    "PROPERTIES_STREAM",
    "SHAPE",
    "SIZE",
    "TASKS",
    "YAWS",
    "Pick",
    "PickPlace",
    "Place",
    "aperture",
    "areas",
    "check_holdable",
    "family",
    "first_hand",
    "one_hand_tabletop",
    "the_object",
]
