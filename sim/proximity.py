"""How close two arms of one robot are: MuJoCo's distance between their collision geoms.

Two arms that move at once can collide where neither planner looked (each plans with the other where it
stands). :class:`ArmProximity` measures the smallest distance between the collision geoms of the bodies two
executors move (from the first joint of each one's last group on: links, hand, fingers) with
``mj_geomDistance``, searching only up to a limit, so that a near miss is seen before any contact is.
"""

from __future__ import annotations

import mujoco
import numpy as np

from besman.sim.executor import Executor


def moved_geoms(executor: Executor) -> list[int]:
    """The collision geoms of the bodies an executor's last joint group moves (links, hand and fingers)."""
    model = executor.world.model
    first_joint = executor.world.robot.group(executor.arm.groups[-1]).joints[0]
    root = model.jnt_bodyid[model.joint(first_joint).id]
    inside = np.zeros(model.nbody, dtype=bool)
    for body in range(model.nbody):  # parents come before their children in MuJoCo's body order
        inside[body] = body == root or (body > 0 and inside[model.body_parentid[body]])
    collides = (model.geom_contype != 0) | (model.geom_conaffinity != 0)
    return [int(g) for g in np.flatnonzero(inside[model.geom_bodyid] & collides)]


class ArmProximity:
    """The distance between two executors' arms (see the module documentation)."""

    def __init__(self, first: Executor, second: Executor) -> None:
        self.world = first.world
        self.pairs = [(a, b) for a in moved_geoms(first) for b in moved_geoms(second)]
        self._line = np.zeros(6)

    def distance(self, limit: float) -> float:
        """The smallest distance between the arms (m), or ``limit`` if they are at least that far apart."""
        model, data, line = self.world.model, self.world.data, self._line
        closest = limit
        for a, b in self.pairs:
            closest = min(closest, mujoco.mj_geomDistance(model, data, a, b, limit, line))
        return closest
