"""What a manipulation left in the world: where a released object came to rest, whether a picked one is up.

The place and pick skills' own criteria, and the predicates tasks compose their success rules from (pick and
place's rule: :mod:`besman.tasks.pick_place.rule`), so that a task's demos, its episodes and the rewards of
its learned blocks judge the same final state the same way.
"""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import dataclass
from typing import TYPE_CHECKING

import numpy as np

from besman.sim.objects import yaw_error, yaw_of

if TYPE_CHECKING:
    from besman.sim.world import World

SETTLE_TIME = 0.3  # s a released box is left to settle before it is judged
PLACE_TOLERANCE = 0.02  # m from the target, in the plane
YAW_TOLERANCE = 5.0  # deg from the wanted yaw, modulo the object's symmetry
TILT_LIMIT = 10.0  # deg from upright
LIFT_HEIGHT = 0.05  # m above where it stood that a picked box must be


@dataclass(frozen=True)
class Placement:
    """Where a released box came to rest: success (upright on the shelf within :data:`PLACE_TOLERANCE` of
    the target and, where a yaw is wanted, within :data:`YAW_TOLERANCE` of it), horizontal error (m), yaw
    error (deg, modulo the object's symmetry; None where no yaw is wanted), tilt, position and a message."""

    success: bool
    error: float
    yaw_error_degrees: float | None
    tilt_degrees: float
    position: tuple[float, float, float]
    message: str


def settle(world: World, observe: Callable[[], None] | None = None) -> None:
    """Lets the world run :data:`SETTLE_TIME` (``observe`` after each step)."""
    import mujoco  # here: tree nodes import the tolerances above, and listing nodes needs no MuJoCo

    for _ in range(round(SETTLE_TIME / world.model.opt.timestep)):
        mujoco.mj_step(world.model, world.data)
        if observe is not None:
            observe()


def placement(
    world: World,
    name: str,
    place_xy,
    observe: Callable[[], None] | None = None,
    yaw: float | None = None,
) -> Placement:
    """Lets the released box ``name`` settle, then judges where it stands against the target ``place_xy``
    and the wanted ``yaw`` (rad; None: any)."""
    settle(world, observe)
    pose = world.object_pose(name)
    item = world.objects[name]
    error = float(np.linalg.norm(pose.position[:2] - np.asarray(place_xy, dtype=float)[:2]))
    turned = None if yaw is None else math.degrees(yaw_error(yaw_of(pose.rotation), yaw, item))
    tilt = math.degrees(math.acos(min(1.0, abs(pose.rotation[2, 2]))))
    on_shelf = abs(pose.position[2] - (world.surface("shelf").height + item.half_height)) < 0.01
    aligned = turned is None or turned <= YAW_TOLERANCE
    success = bool(error <= PLACE_TOLERANCE and aligned and tilt < TILT_LIMIT and on_shelf)
    message = (
        "placed"
        if success
        else (
            f"placed {error * 100:.1f} cm from the target"
            + ("" if turned is None else f", turned {turned:.1f} deg from its yaw")
            + f", tilted {tilt:.1f} deg"
            + ("" if on_shelf else ", off the shelf")
        )
    )
    position = tuple(round(float(v), 4) for v in pose.position)
    return Placement(success, error, turned, tilt, position, message)


def lifted(world: World, hand, name: str, tolerance: float = 0.005) -> bool:
    """The box ``name`` is in ``hand`` and :data:`LIFT_HEIGHT` (less ``tolerance``) above the table."""
    resting = world.surface("table").height + world.objects[name].half_height
    return bool(hand.holds(name) and world.object_pose(name).position[2] >= resting + LIFT_HEIGHT - tolerance)
