"""Stack: the robot stacks three boxes (red, green, blue) on a spot on the table, in the order tau gives,
with its first arm (default tree ``stack.yaml``: one subtree in a loop over the blackboard's list
``/task/objects``, each item a box and where it goes: x, y, yaw 0 and the height of the top it is set down
on).

- **Randomised**: tau = ``spot`` (x, y of the stack on the table, m, in the robot's spot area: the
  built-in robots' :data:`LAYOUTS`; a brought robot's description section ``"tasks": {"stack": {"spot":
  {"x": [x0, x1], "y": [y0, y1]}, "starts": [[x, y], [x, y], [x, y]]}}`` (starts: red, green, blue), or
  without one, the corners of its ``tabletop.reach``, :func:`derived`) and ``order`` (which box goes where,
  bottom to top: one of the six orders of :data:`ORDERS`, 0-5); the seed also moves each box's start (the
  robot's three) by up to :data:`JITTER` in x and y. Without a seed: the middle of the spot area, order 0
  and seed 0's draws.
- **Success**: after the tree, the stack stands: for :data:`STANDING_TIME` (2 s) of simulation every box
  stays within :data:`TOLERANCE` (1 cm) of the spot in x and y, and at the end each box is at its level
  (within 1 cm of its height in a stack of 6 cm boxes).
"""

from __future__ import annotations

import itertools
from collections.abc import Mapping
from dataclasses import dataclass
from typing import ClassVar

import numpy as np

from besman.core.seeds import child_seed
from besman.skills.task_bounds import TaskBounds
from besman.tasks.base import Scene, Task, TaskValue
from besman.tasks.pick_place.scene import first_hand

BOXES = {"red": (0.80, 0.15, 0.12, 1.0), "green": (0.20, 0.62, 0.25, 1.0), "blue": (0.15, 0.35, 0.80, 1.0)}
ORDERS = tuple(itertools.permutations(BOXES))  # bottom to top


@dataclass(frozen=True)
class StackLayout:
    """A robot's stack: the area of the spot (x and y ranges, m) and where the three boxes start (x, y)."""

    spots: tuple[tuple[float, float], tuple[float, float]]
    starts: tuple[tuple[float, float], ...]


# Per robot, on the part of its table where the first arm plans top-down grasps and placings up to two
# boxes high (a grid of 4 cm, planned from home: AILA x 0.43-0.71, y -0.22..0.18 m; the UR5e all of its
# table's front; the OpenArm only x 0.14-0.30, y -0.22..-0.02 m): the boxes 12-14 cm from each other and
# farther from the spot, where the open fingers keep clear of the neighbours (on the OpenArm at the corners
# of its small area). What failed on the way: a spot between the home and the boxes (AILA's hand comes from
# (0.73, -0.54, 1.33) m: its reach to the next box swept the stack off), a spot 3 cm from the shelf (the
# fingers caught its edge setting the top box down: the UR5e at y = -0.218 m), a box so far from the spot
# that the joint-space carry dipped it to the table (AILA from y = +0.08 m to -0.2 m) or so far out that
# the reach left a joint's range (AILA's wrist at x = 0.68 m).
LAYOUTS = {
    "aila": StackLayout(((0.51, 0.57), (0.09, 0.13)), ((0.45, -0.10), (0.58, -0.08), (0.52, -0.20))),
    "ur5e": StackLayout(((0.38, 0.47), (-0.20, -0.17)), ((0.38, -0.04), (0.52, -0.04), (0.60, -0.14))),
    "openarm": StackLayout(((0.15, 0.18), (-0.21, -0.18)), ((0.29, -0.21), (0.15, -0.05), (0.29, -0.05))),
}
# A brought robot's stack without a section of its own (derived): the three boxes and the spot in the four
# corners of the area its first arm reaches, at least 12 cm apart (the open fingers keep clear of the
# neighbours, as in sort), the spot drawn in a 2 cm square (on the WidowX AI the boxes' 13 cm apart, the
# spot 11-13 cm from the nearest).
DERIVED_SIDE = 0.12
DERIVED_SPOT = 0.02
JITTER = 0.005  # m a seed moves each box's start by, at most, in x and in y
# m added per level to the top a box is set down on: a box on a box stands a little higher than 6 cm a
# level (a tilt, the contacts), and the fingers that set the next one down come within a few mm of it.
GAP = 0.003
STANDING_TIME = 2.0  # s the stack must stand
TOLERANCE = 0.01  # m from the spot in x and y, and from its level in z
UNSEEDED = 0  # the seed whose draws a run without a seed uses
BOX_STREAM = 1  # the child of the run's seed that draws where the boxes stand


class Stack(Task):
    name = "stack"
    section = "spot and starts: where the tower stands and the three boxes start"
    title = "stack three boxes on a spot on the table, in the order tau gives"
    randomised = "the stack's spot and the boxes' order (tau), and where the boxes stand before"
    success = "the stack stands for 2 s: every box within 1 cm of the spot in x and y, and at its level"
    robot = "aila"
    tree = "stack.yaml"
    values = (
        TaskValue("spot", ("spot_x", "spot_y"), "m", "where the stack stands", surface="table", target=True),
        TaskValue("order", ("order",), "", "which box goes where, bottom to top (ORDERS)", whole=True),
    )
    measurements: ClassVar[Mapping[str, str]] = {
        "order": "the boxes bottom to top",
        "largest_offsets_m": "each box's largest distance from the spot in x and y while the stack stood",
        "level_errors_m": "each box's distance from its level in the stack at the end",
    }
    max_sim_time = 240.0

    def fits(self, robot) -> bool:
        return first_hand(robot) and _layout(str(robot.folder)) is not None

    def bounds(self, robot: str) -> TaskBounds:
        (x0, x1), (y0, y1) = _layout(robot).spots
        return TaskBounds(self.names, (x0, y0, 0), (x1, y1, len(ORDERS) - 1))

    def scene(self, robot: str, values, seed: int | None) -> Scene:
        from besman.sim.executor import Executor
        from besman.sim.world import GraspableObject, tabletop_world

        # A stream of the seed's own for the boxes: tau's draws (resolve) stay what they are without them.
        rng = np.random.default_rng(child_seed(UNSEEDED if seed is None else seed, BOX_STREAM))
        starts = np.asarray(_layout(robot).starts)
        spots = (starts + rng.uniform(-JITTER, JITTER, starts.shape)).round(4)
        spot = values["spot"]
        world = tabletop_world(tuple(GraspableObject(name, rgba=rgba) for name, rgba in BOXES.items()), robot)
        for name, (x, y) in zip(BOXES, spots, strict=True):
            world.place_on(name, "table", x, y)
        order = ORDERS[int(values["order"][0])]
        table, height = world.surface("table").height, 2 * world.objects["red"].half_height
        items = [
            {"object": name, "target": [*spot.tolist(), 0.0, round(table + level * (height + GAP), 4)]}
            for level, name in enumerate(order)
        ]
        settings = {
            "objects": {name: spot.tolist() for name, spot in zip(BOXES, spots, strict=True)},
            "order": list(order),
            "spot": spot.tolist(),
        }
        return Scene(
            Executor(world), {**values, "objects": items}, settings, lambda: self.judge(world, spot, order)
        )

    def judge(self, world, spot, order):
        """The success rule on ``world`` as it stands (see the module documentation)."""
        import mujoco

        from besman.trees.summary import Measured

        offsets = dict.fromkeys(order, 0.0)
        for _ in range(round(STANDING_TIME / world.model.opt.timestep)):
            mujoco.mj_step(world.model, world.data)
            for name in order:
                xy = world.object_pose(name).position[:2]
                offsets[name] = max(offsets[name], float(np.linalg.norm(xy - spot)))
        table = world.surface("table").height
        levels = {
            name: abs(
                float(world.object_pose(name).position[2])
                - table
                - (2 * k + 1) * world.objects[name].half_height
            )
            for k, name in enumerate(order)
        }
        standing = all(offset <= TOLERANCE for offset in offsets.values()) and all(
            error <= TOLERANCE for error in levels.values()
        )
        worst = max(order, key=offsets.get)
        return Measured(
            standing,
            f"the stack {'stood' if standing else 'did not stand'} {STANDING_TIME:g} s; largest offset "
            f"{offsets[worst] * 100:.1f} cm ({worst})",
            {
                "order": list(order),
                "largest_offsets_m": {name: round(offset, 4) for name, offset in offsets.items()},
                "level_errors_m": {name: round(error, 4) for name, error in levels.items()},
            },
        )

    def facts(self, robot: str) -> dict:
        return {"orders": [list(order) for order in ORDERS]}


def _layout(robot: str) -> StackLayout | None:
    """``robot``'s stack: :data:`LAYOUTS`' by its name, its description's ``tasks.stack`` section or, for a
    brought robot with a tabletop and neither, one in the area its first arm reaches (:func:`derived`);
    None where it has no tabletop (or an area too small for one)."""
    import besman.robots as robots

    found = Stack().robot_numbers(robot, LAYOUTS, _read_layout)
    if found is not None:
        return found
    tabletop = robots.describe(robot).tabletop
    return None if tabletop is None else derived(tabletop)


def derived(tabletop) -> StackLayout | None:
    """A stack in the corners of the area the first arm reaches (``tabletop.reach``): the spot in the corner
    farthest from the shelf (a :data:`DERIVED_SPOT` square), a box in each other corner; None where a side
    of the area is shorter than :data:`DERIVED_SIDE`."""
    (x0, x1), (y0, y1) = tabletop.reach
    if min(x1 - x0, y1 - y0) < DERIVED_SIDE:
        return None
    shelf = np.array([sum(tabletop.shelf.x) / 2, sum(tabletop.shelf.y) / 2])
    corners = [(x, y) for x in (x0, x1) for y in (y0, y1)]
    spot = max(corners, key=lambda corner: float(np.linalg.norm(np.subtract(corner, shelf))))
    inner = np.round(spot + np.sign(np.array([x0 + x1, y0 + y1]) / 2 - spot) * DERIVED_SPOT, 4)
    spots = tuple((float(min(a, b)), float(max(a, b))) for a, b in zip(spot, inner, strict=True))
    return StackLayout(spots, tuple(corner for corner in corners if corner != spot))


def _read_layout(value: dict, where: str, tabletop) -> StackLayout:
    """A description's ``tasks.stack``: ``{"spot": {"x": [x0, x1], "y": [y0, y1]}, "starts": [[x, y] x 3]}``
    (m, on the table)."""
    from besman.robots.fields import DescriptionError, finite_numbers
    from besman.robots.tabletop import read_area, section

    given = section(value, where, ("spot",), ("starts",))  # starts: a list, checked here
    spots = read_area(given["spot"], f"{where}.spot", None if tabletop is None else tabletop.table)
    starts = given.get("starts")
    if not isinstance(starts, list) or len(starts) != len(BOXES):
        raise DescriptionError(f"{where}.starts: expected {len(BOXES)} [x, y] (where the boxes start)")
    return StackLayout(
        spots, tuple(finite_numbers(start, f"{where}.starts[{k}]", 2) for k, start in enumerate(starts))
    )


TASKS = (Stack(),)
