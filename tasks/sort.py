"""Sort: the robot puts three boxes (red, green, blue) from the table on the shelf, each in its own place,
one after the other with its first arm (default tree ``sort.yaml``; ``sort_learned.yaml`` moves the arm with
the pick-and-place pool's templates: one subtree in a loop over the
blackboard's list ``/task/objects``). During one box's carry a person takes it out of the hand and sets it
down elsewhere on the table (:class:`~besman.sim.disturbances.TakeFromHand`); nothing tells the robot, and
the tree grasps the box again where it now lies.

- **Randomised**: where the boxes stand, tau = ``red``, ``green``, ``blue`` (x, y each, m), drawn together
  in the table area the first arm reaches (its description's ``tabletop.reach``, :data:`AREA_SHIFT`) until
  every two are :data:`SPACING` apart; then, from the same seed, which box slips, where it is set down (as
  far from the boxes still waiting) and how long into its carry (:data:`SLIP_AFTER`). A run without a seed
  uses seed 0's draws. The places are fixed: around the middle of the robot's place area of pick and place
  (:func:`~besman.tasks.pick_place.areas`), :data:`PLACE_OFFSETS`.
- **Success**: every box passes pick and place's rule (:func:`~besman.sim.outcomes.placement`:
  after 0.3 s to settle it stands upright, tilt < 10 deg, on the shelf within 2 cm of its own place) and
  the slip came.
"""

from __future__ import annotations

import itertools
from collections.abc import Mapping
from typing import ClassVar

import numpy as np

from besman.core.errors import InputError
from besman.skills.task_bounds import TaskBounds
from besman.tasks.base import Scene, Task, TaskValue
from besman.tasks.pick_place.scene import areas, family, one_hand_tabletop

BOXES = {"red": (0.80, 0.15, 0.12, 1.0), "green": (0.20, 0.62, 0.25, 1.0), "blue": (0.15, 0.35, 0.80, 1.0)}
SIDE = 0.06  # m: the boxes are cubes this size, or as wide as the robot's gripper holds (if less)
# Each box's own place on the shelf, from the middle of the place area, 14-15 cm apart (the open hand spans
# 9 cm, plus the fingers). The carried box clears the shelf by 6 cm, as high as a box that stands there, so
# the far place is filled first and no carry passes over a placed box. (On AILA: blue (0.52, -0.50), red
# (0.45, -0.37), green (0.60, -0.37).)
PLACE_OFFSETS = {"blue": (-0.015, -0.09), "red": (-0.085, 0.04), "green": (0.065, 0.04)}
# Where the boxes stand, from the area the first arm reaches: 2 cm farther and 1 cm more to the right (on
# AILA: x, y from (0.47, -0.16) to (0.64, 0.0), the right arm's top-down grasps from its home pose).
AREA_SHIFT = ((0.02, 0.02), (-0.01, 0.0))
SPACING = 0.12  # m between the boxes on the table: the open fingers keep clear of the neighbours
SLIP_AFTER = (0.3, 0.9)  # s into the carry at which the slipping box is taken out of the hand (drawn)
UNSEEDED = 0  # the seed whose draws a run without a seed uses


def places(robot: str) -> dict[str, tuple[float, float]]:
    """Each box's place on ``robot``'s shelf."""
    (x0, x1), (y0, y1) = areas(robot)[1]
    x, y = round((x0 + x1) / 2, 4), round((y0 + y1) / 2, 4)
    return {name: (round(x + dx, 4), round(y + dy, 4)) for name, (dx, dy) in PLACE_OFFSETS.items()}


def free_spots(rng: np.random.Generator, low, high, count: int, taken=()) -> np.ndarray:
    """``count`` spots (x, y rows, to 0.1 mm) drawn in the box ``low``-``high``, each :data:`SPACING` from
    the others and from ``taken``."""
    taken = [np.asarray(spot, dtype=float) for spot in taken]
    for _ in range(10_000):  # all at once, so that early spots cannot leave no room for later ones
        spots = rng.uniform(low, high, size=(count, 2))
        together = [*taken, *spots]
        if all(np.linalg.norm(a - b) >= SPACING for a, b in itertools.combinations(together, 2)):
            return spots.round(4)
    raise AssertionError("no room on the table for the boxes")  # the areas leave room: not reached


class Sort(Task):
    name = "sort"
    title = "put three boxes on the shelf, each in its own place; one is taken out of the hand on the way"
    randomised = "where the boxes stand on the table (tau), which box slips, when, and where it is set down"
    success = (
        "after settling 0.3 s every box stands upright (tilt < 10 deg) on the shelf within 2 cm of its own "
        "place, and the slip came"
    )
    robot = "aila"
    tree = "sort.yaml"
    values = tuple(
        TaskValue(name, (f"{name}_x", f"{name}_y"), "m", f"where the {name} box stands on the table")
        for name in BOXES
    )
    measurements: ClassVar[Mapping[str, str]] = {
        "placement_errors_m": "each box's distance from its own place on the shelf, by box",
        "tilts_deg": "each box's tilt from upright, by box",
        "slipped": "the box taken out of the hand during its carry (None if the slip never came)",
    }
    max_sim_time = 240.0

    def fits(self, robot) -> bool:
        return one_hand_tabletop(robot)

    def bounds(self, robot: str) -> TaskBounds:
        (x0, x1), (y0, y1) = areas(self.check_robot(robot))[0]  # a robot it does not fit is refused by name
        (dx0, dx1), (dy0, dy1) = AREA_SHIFT
        low, high = (round(x0 + dx0, 4), round(y0 + dy0, 4)), (round(x1 + dx1, 4), round(y1 + dy1, 4))
        return TaskBounds(self.names, low * len(BOXES), high * len(BOXES))

    def draw(self, robot: str, rng: np.random.Generator) -> np.ndarray:
        """The boxes' spots, drawn together until every two are :data:`SPACING` apart."""
        bounds = self.bounds(robot)
        return free_spots(rng, bounds.low[:2], bounds.high[:2], len(BOXES)).ravel()

    def default_values(self, robot: str) -> dict[str, np.ndarray]:
        return self.split(self.draw(robot, np.random.default_rng(UNSEEDED)))

    def resolve(self, robot: str, given, seed: int | None) -> dict[str, np.ndarray]:
        """As :meth:`Task.resolve`; boxes closer than :data:`SPACING` are refused too."""
        values = super().resolve(robot, given, seed)
        for first, second in itertools.combinations(BOXES, 2):
            gap = float(np.linalg.norm(values[first] - values[second]))
            if gap < SPACING:
                raise InputError(
                    f"--set: the {first} and {second} boxes would stand {gap * 100:.1f} cm apart; boxes need "
                    f"{SPACING * 100:.0f} cm between them"
                )
        return values

    def scene(self, robot: str, values, seed: int | None) -> Scene:
        from besman.sim.disturbances import TakeFromHand
        from besman.sim.executor import Executor
        from besman.sim.world import GraspableObject, tabletop_world

        rng = np.random.default_rng(UNSEEDED if seed is None else seed)
        self.draw(robot, rng)  # the seed drew the spots first (resolve); the slip's draws follow them
        spots = {name: tuple(values[name].tolist()) for name in BOXES}
        targets = places(robot)
        order = sorted(BOXES, key=lambda name: targets[name][1])  # the far places first
        slipping = order[int(rng.integers(len(order)))]
        # It is set down clear of the boxes still on the table then (those after it in the loop).
        waiting = [spots[name] for name in order[order.index(slipping) + 1 :]]
        bounds = self.bounds(robot)
        set_down = free_spots(rng, bounds.low[:2], bounds.high[:2], 1, waiting)[0]
        slip = TakeFromHand(slipping, tuple(set_down.tolist()), after=float(rng.uniform(*SLIP_AFTER)))
        half = min(SIDE, family(robot).width[1]) / 2  # cubes the robot's gripper holds
        boxes = tuple(GraspableObject(name, size=(half,) * 3, rgba=rgba) for name, rgba in BOXES.items())
        world = tabletop_world(boxes, robot)
        for name, (x, y) in spots.items():
            world.place_on(name, "table", x, y)
        items = [{"object": name, "target": list(targets[name])} for name in order]
        settings = {
            "objects": spots,
            "places": {name: list(targets[name]) for name in order},
            "slip": {"object": slip.object, "after_s": round(slip.after, 3), "set_down_at": list(slip.where)},
        }
        return Scene(
            Executor(world),
            {**values, "objects": items},
            settings,
            lambda: self.judge(world, targets, slip),
            observe=lambda runner, _: slip(runner.executor),
        )

    def judge(self, world, targets, slip):
        """The success rule on ``world`` as it stands (see the module documentation)."""
        from besman.sim.outcomes import placement
        from besman.trees.summary import Measured

        placed = {name: placement(world, name, targets[name]) for name in BOXES}
        errors = ", ".join(f"{name} {found.error * 100:.1f} cm" for name, found in placed.items())
        misses = "; ".join(f"{name} {found.message}" for name, found in placed.items() if not found.success)
        slipped = slip.object if slip.done else None
        return Measured(
            all(found.success for found in placed.values()) and slip.done,
            f"placement errors {errors}"
            + (f" ({misses})" if misses else "")
            + (f"; {slipped} slipped and was grasped again" if slipped else "; the slip never came"),
            {
                "placement_errors_m": {name: round(found.error, 4) for name, found in placed.items()},
                "tilts_deg": {name: round(found.tilt_degrees, 2) for name, found in placed.items()},
                "slipped": slipped,
            },
        )

    def facts(self, robot: str) -> dict:
        return {"places": {name: list(place) for name, place in places(robot).items()}}


TASKS = (Sort(),)
