"""Grasp sensing: whether a gripper's finger pads touch an object and the object moves with the hand.

A grasp is judged from the simulation as a robot with touch sensing would: both finger pads (the collision
geoms of the finger bodies) in contact with the object, and the object's linear velocity within 2 cm/s of
the hand site's, so that an object merely brushed or pushed does not count as held.
"""

from __future__ import annotations

import mujoco
import numpy as np

from besman.robots import JointGroup
from besman.sim.world import World

HELD_SPEED = 0.02  # m/s: largest object-vs-hand speed of a held object


class Hand:
    """The finger pads and hand site of ``gripper`` (a joint group of ``world``'s robot)."""

    def __init__(self, world: World, gripper: JointGroup) -> None:
        self.world, self.gripper = world, gripper
        model = world.model
        bodies = [model.jnt_bodyid[model.joint(name).id] for name in gripper.joints]
        self.pads = tuple(int(np.flatnonzero(model.geom_bodyid == body)[0]) for body in bodies)
        self.site = model.site(gripper.site).id
        self._velocity = np.empty(6)

    def touching(self, name: str) -> tuple[bool, bool]:
        """Whether each finger pad touches the object ``name``."""
        model, data = self.world.model, self.world.data
        geoms = data.contact.geom  # (ncon, 2), one vectorised pass over the contacts
        bodies = model.geom_bodyid[geoms]
        target = model.body(name).id
        touch = []
        for pad in self.pads:
            first, second = geoms[:, 0] == pad, geoms[:, 1] == pad
            other = np.where(first, bodies[:, 1], bodies[:, 0])
            touch.append(bool(np.any((first | second) & (other == target))))
        return touch[0], touch[1]

    def holds(self, name: str | None) -> bool:
        """Both pads touch the object and it moves with the hand."""
        if name is None or not all(self.touching(name)):
            return False
        model, data = self.world.model, self.world.data
        mujoco.mj_objectVelocity(
            model, data, mujoco.mjtObj.mjOBJ_BODY, model.body(name).id, self._velocity, 0
        )
        body = self._velocity[3:].copy()
        mujoco.mj_objectVelocity(model, data, mujoco.mjtObj.mjOBJ_SITE, self.site, self._velocity, 0)
        return bool(np.linalg.norm(body - self._velocity[3:]) < HELD_SPEED)
