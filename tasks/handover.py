"""Handover: a two-arm robot's left hand hands a bar to its right hand, which puts it on the shelf (default
tree ``handover.yaml``).

The left arm picks the 26 cm bar from the table's left side at one end while the right arm waits at the
``ready`` pose; the left presents the bar in front of the body (``present``), the right hand takes the
other end, the left lets go, rises and goes home, and the right arm puts the bar on the shelf. The poses,
areas and grip are the robot's (:data:`HANDOVER`, or its description's ``tasks.handover`` section: ``bar``
and ``places`` areas, ``ready`` and ``present`` hand poses, read as
:func:`~besman.robots.tabletop.read_area` and :func:`~besman.robots.tabletop.read_hand_pose` read
them, and optionally ``grip``, :class:`HandoverNumbers`).

- **Randomised**: tau = ``bar`` (x, y of its middle on the table) and ``place`` (x, y of its target on the
  shelf), drawn uniformly from the robot's areas, bar first. Without a seed: the middle of both areas.
- **Success**: the bar passes pick and place's rule (:func:`~besman.sim.outcomes.placement`: after
  0.3 s to settle it lies level, tilt < 10 deg, on the shelf within 2 cm of the place) and the two arms
  never touched (:class:`ArmContacts`: no tick with a contact between them in the simulation).
"""

from __future__ import annotations

from collections.abc import Iterator, Mapping
from dataclasses import asdict, dataclass
from typing import TYPE_CHECKING, ClassVar

import numpy as np

from besman.core.errors import InputError
from besman.sim.objects import GraspableObject
from besman.skills.task_bounds import TaskBounds
from besman.tasks.base import Scene, Task, TaskValue

if TYPE_CHECKING:
    from besman.sim.executor import Executor
    from besman.sim.world import World
    from besman.tasks.robot_check import Finding

Area = tuple[tuple[float, float], tuple[float, float]]  # (x0, x1), (y0, y1) in m


BAR_HALF_LENGTH = 0.13  # m: the bar is 26 cm long
# A bar, so that two hands can hold it at once from above, 12 cm apart: 26 x 4 x 4 cm, along y.
BAR = GraspableObject("bar", size=(0.02, BAR_HALF_LENGTH, 0.02), mass=0.2, rgba=(0.85, 0.65, 0.15, 1.0))
GRIP = 0.08  # m from the bar's middle where each hand holds it, unless the robot says otherwise
# The grips a robot may give: the hands' pads (4 cm) on the bar, and the hands apart.
GRIPS = (0.04, BAR_HALF_LENGTH - 0.02)
# deg the bar held by one end may turn on in the grip in robot_check.HOLD_TIME, settled (``besman robots
# check``; the two WidowX AI without the no-slip solver: 2.8; AILA, the OpenArm, the WidowX AI with it: 0.1
# at most).
BAR_TURN = 1.0


@dataclass(frozen=True)
class HandoverNumbers:
    """A robot's handover: where the left hand picks the bar on the table, where the right hand puts it on
    the shelf (areas), where the right hand waits and where the left presents the bar (hand poses, as the
    tree reads them: ``{"position": [x, y, z], "yaw": rad}``, yaw optional), and how far from the bar's
    middle each hand holds it (``grip``, m: the left at +grip along the bar, the right at -grip; wide
    wrists need their hands farther apart)."""

    bar: Area
    places: Area
    ready: dict
    present: dict
    grip: float = GRIP


# Each robot's README says where its numbers come from (the OpenArm's bar area is the left hand's mirror of
# the right's reach; its right hand waits near home).
HANDOVER = {
    "aila": HandoverNumbers(
        bar=((0.45, 0.5), (0.15, 0.22)),
        places=((0.5, 0.55), (-0.45, -0.38)),
        ready={"position": (0.5, -0.25, 0.95), "yaw": -0.8},
        present={"position": (0.44, 0.06, 0.86)},
    ),
    "openarm": HandoverNumbers(
        bar=((0.18, 0.26), (0.08, 0.16)),
        places=((0.18, 0.26), (-0.42, -0.38)),
        ready={"position": (0.23, -0.16, 1.02)},
        present={"position": (0.25, 0.06, 0.95)},
    ),
}
ARMS = ("right", "left")  # the right arm places, the left picks


def _read_handover(section: dict, where: str, layout) -> HandoverNumbers:
    """A description's ``tasks.handover``, its areas on ``layout``'s table and shelf."""
    from besman.robots.fields import DescriptionError
    from besman.robots.tabletop import read_area, read_hand_pose
    from besman.robots.tabletop import section as fields

    section = fields(section, where, ("bar", "places", "ready", "present"), optional=("grip",))
    grip = section.get("grip", GRIP)
    if isinstance(grip, bool) or not isinstance(grip, int | float) or not GRIPS[0] <= grip <= GRIPS[1]:
        raise DescriptionError(
            f"{where}.grip: how far from the bar's middle each hand holds it, {GRIPS[0]}-{GRIPS[1]} m "
            f"(the bar is {2 * BAR_HALF_LENGTH:.2f} m long), got {grip!r}"
        )
    return HandoverNumbers(
        bar=read_area(section["bar"], f"{where}.bar", layout.table),
        places=read_area(section["places"], f"{where}.places", layout.shelf),
        ready=asdict(read_hand_pose(section["ready"], f"{where}.ready")),
        present=asdict(read_hand_pose(section["present"], f"{where}.present")),
        grip=float(grip),
    )


class ArmContacts:
    """An observer of two arms, every tick: the ticks at which they touch (a contact between their collision
    geoms in the simulation) and the closest they came (MuJoCo's geom distance, searched up to 0.5 m)."""

    def __init__(self, first: Executor, second: Executor) -> None:
        from besman.sim.proximity import ArmProximity, moved_geoms

        self.world = first.world
        self.first, self.second = np.array(moved_geoms(first)), np.array(moved_geoms(second))
        self.proximity = ArmProximity(first, second)
        self.touching = 0
        self.closest = 0.5

    def __call__(self, runner, record: dict) -> None:
        data = self.world.data
        geoms = data.contact.geom[: data.ncon]
        one = np.isin(geoms[:, 0], self.first) & np.isin(geoms[:, 1], self.second)
        other = np.isin(geoms[:, 1], self.first) & np.isin(geoms[:, 0], self.second)
        self.touching += bool((one | other).any())
        self.closest = min(self.closest, self.proximity.distance(self.closest))


class Handover(Task):
    name = "handover"
    section = "bar, places, ready, present and grip: where the bar lies and goes, the hands' poses, the grip"
    title = "the left hand picks a bar and hands it to the right, which puts it on the shelf"
    randomised = "where the bar lies on the table and its target on the shelf (tau)"
    success = (
        "after settling 0.3 s the bar lies level (tilt < 10 deg) on the shelf within 2 cm of the target, "
        "and the arms never touched"
    )
    robot = "aila"
    tree = "handover.yaml"
    values = (
        TaskValue("bar", ("bar_x", "bar_y"), "m", "where the bar's middle lies on the table"),
        TaskValue("place", ("place_x", "place_y"), "m", "where the bar goes on the shelf"),
    )
    measurements: ClassVar[Mapping[str, str]] = {
        "placement_error_m": "the bar's distance from its place on the shelf, in the plane",
        "tilt_deg": "the bar's tilt from level",
        "ticks_arms_touching": "ticks at which the two arms touched in the simulation (success: none)",
        "arms_closest_m": "the closest the arms came (searched up to 0.5 m)",
    }

    def numbers(self, robot: str) -> HandoverNumbers | None:
        """The handover on ``robot``: :data:`HANDOVER`'s or its description's ``tasks.handover``; None if
        neither has it, or the robot has no tabletop."""
        import besman.robots as robots

        if robots.describe(robot).tabletop is None:
            return None
        return self.robot_numbers(robot, HANDOVER, _read_handover)

    def fits(self, robot) -> bool:
        """Two arms "right" and "left", each with a gripper, and the robot's handover numbers."""
        arms = robot.arms
        return all(side in arms and arms[side].gripper is not None for side in ARMS) and (
            self.numbers(str(robot.folder)) is not None
        )

    def bounds(self, robot: str) -> TaskBounds:
        numbers = self.numbers(robot)
        if numbers is None:
            raise InputError(
                f"robot {robot!r} has no handover numbers (its description's tasks.handover): task "
                f"{self.name} does not run on it"
            )
        (bx, by), (px, py) = numbers.bar, numbers.places
        return TaskBounds(self.names, (bx[0], by[0], px[0], py[0]), (bx[1], by[1], px[1], py[1]))

    def draw(self, robot: str, rng: np.random.Generator) -> np.ndarray:
        """As :meth:`Task.draw`, to 0.1 mm: a seed gives the configuration it gave the handover demo."""
        return super().draw(robot, rng).round(4)

    def scene(self, robot: str, values, seed: int | None) -> Scene:
        from besman.sim.executor import Executor
        from besman.sim.world import tabletop_world

        numbers = self.numbers(robot)
        world = tabletop_world((BAR,), robot)
        world.place_on("bar", "table", *values["bar"])
        # Both arms at once: the waist they share is held (a turning torso would carry the left hand, and
        # the bar, with it).
        executor = Executor(world, ARMS)
        contacts = ArmContacts(executor, executor.arm_executor("left"))
        return Scene(
            executor,
            {**values, **self._poses(numbers)},
            {name: value.tolist() for name, value in values.items()},
            lambda: self.judge(world, values["place"], contacts),
            observe=contacts,
        )

    def judge(self, world, place, contacts: ArmContacts):
        """The success rule on ``world`` as it stands (see the module documentation)."""
        from besman.sim.outcomes import placement
        from besman.trees.summary import Measured

        placed = placement(world, "bar", place)
        return Measured(
            placed.success and contacts.touching == 0,
            f"placement error {placed.error * 100:.1f} cm"
            + ("" if placed.success else f" ({placed.message})")
            + f"; the arms came within {contacts.closest * 100:.1f} cm and touched at {contacts.touching} "
            "ticks",
            {
                "placement_error_m": round(placed.error, 4),
                "tilt_deg": round(placed.tilt_degrees, 2),
                "ticks_arms_touching": contacts.touching,
                "arms_closest_m": round(contacts.closest, 4),
            },
        )

    @staticmethod
    def _poses(numbers: HandoverNumbers) -> dict:
        """The robot's handover values the tree reads: where the hands wait and meet, where each holds."""
        return {
            "ready": numbers.ready,
            "present": numbers.present,
            "left_grip": (0.0, numbers.grip),
            "right_grip": (0.0, -numbers.grip),
        }

    def facts(self, robot: str) -> dict:
        return {"handover": self._poses(self.numbers(robot))}

    def robot_checks(self, robot: str, description) -> Iterator[Finding]:
        """On a robot the handover fits: the left hand holds the bar by one end for the right to take it
        (:func:`holds_bar`)."""
        if not self.fits(description):
            return
        from besman.sim.world import tabletop_world

        with_bar = tabletop_world((BAR,), robot=robot)
        yield holds_bar(with_bar, "left", self.numbers(robot).grip, str(description.file))


def holds_bar(world: World, name: str, grip: float, field: str) -> Finding:
    """The bar closed on by arm ``name``'s hand :attr:`HandoverNumbers.grip` from its middle, then its
    weight on: after :data:`~besman.tasks.robot_check.HOLD_SETTLE` s to settle in the grip (a hand may hold
    it at a slant), it must not turn on by more than :data:`BAR_TURN` in
    :data:`~besman.tasks.robot_check.HOLD_TIME` s (a grip whose contacts let it creep drops its far end as
    the arm moves, and the other hand comes down beside it)."""
    from besman.tasks.robot_check import HOLD_SETTLE, HOLD_TIME, Finding, closed_on, settled_then_held

    closed_on(world, name, BAR, along=grip)

    def tilt() -> float:
        length = world.object_pose(BAR.name).rotation[:, 1]
        return float(np.degrees(np.arcsin(np.clip(length[2], -1.0, 1.0))))

    settled, held = settled_then_held(world, tilt)
    turned = abs(held - settled)
    return Finding(
        name,
        "holds the handover's bar by one end",
        turned <= BAR_TURN,
        f"the {2 * BAR.size[1] * 100:.0f} cm bar held {grip * 100:.0f} cm from its middle, after "
        f"{HOLD_SETTLE:g} s to settle: it turned {turned:.1f} deg in {HOLD_TIME:g} s (at most {BAR_TURN:g})",
        f"MuJoCo's no-slip solver ({field}: options.noslip_iterations, e.g. 10), or the hands nearer the "
        "bar's middle (tasks.handover.grip)",
    )


TASKS = (Handover(),)
