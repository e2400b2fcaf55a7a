"""Grasp sensing: whether a gripper's finger pads touch an object and the object moves with the hand.

A grasp is judged from the simulation as a robot with touch sensing would: both sides' finger pads (the pad
geoms the robot's description names) in contact with the object, and the object's linear velocity within
2 cm/s of the hand's at the object's centre, so that an object merely brushed or pushed does not count as
held.
"""

from __future__ import annotations

import mujoco
import numpy as np

from besman.robots import RobotArm
from besman.sim.world import World

HELD_SPEED = 0.02  # m/s: largest object-vs-hand speed of a held object


class Hand:
    """The finger pads and tool site of ``arm`` (an arm with a gripper of ``world``'s robot)."""

    def __init__(self, world: World, arm: RobotArm) -> None:
        self.world, self.gripper = world, arm.gripper
        self.fingers = world.robot.group(self.gripper.group)  # the fingers' joints
        self.pads = self.gripper.pads  # geom ids, per side
        self.site = world.model.site(arm.tcp).id
        self._velocity = np.empty(6)
        self._bodies: dict[str, int] = {}  # body ids by name (a name lookup costs more than the check)

    def _body(self, name: str) -> int:
        if name not in self._bodies:
            self._bodies[name] = self.world.object_body(name)
        return self._bodies[name]

    def touching(self, name: str) -> tuple[bool, bool]:
        """Whether each side's pads touch the object ``name``."""
        geoms = self.world.data.contact.geom  # (ncon, 2), one vectorised pass over the contacts
        on_target = self.world.model.geom_bodyid[geoms] == self._body(name)
        # A pad touches the object where it is one side of a contact and the object's body the other.
        touching_geoms = np.r_[geoms[on_target[:, 1], 0], geoms[on_target[:, 0], 1]]
        first, second = (bool(np.isin(side, touching_geoms).any()) for side in self.pads)
        return first, second

    def bumps(self, name: str) -> bool:
        """Whether any part of the robot touches the object ``name``."""
        model, data = self.world.model, self.world.data
        bodies = model.geom_bodyid[data.contact.geom]  # (ncon, 2)
        on_object = bodies == self._body(name)
        others = np.r_[bodies[on_object[:, 1], 0], bodies[on_object[:, 0], 1]]
        robot = model.body_rootid[model.site_bodyid[self.site]]
        return bool((model.body_rootid[others] == robot).any())

    def holds(self, name: str | None) -> bool:
        """Both pads touch the object and it moves with the hand."""
        if name is None or not all(self.touching(name)):
            return False
        return self.slip(name) < HELD_SPEED

    def slip(self, name: str) -> float:
        """How fast (m/s) the object ``name`` moves against the hand at its centre."""
        model, data = self.world.model, self.world.data
        body = self._body(name)
        mujoco.mj_objectVelocity(model, data, mujoco.mjtObj.mjOBJ_BODY, body, self._velocity, 0)
        moving = self._velocity[3:].copy()
        mujoco.mj_objectVelocity(model, data, mujoco.mjtObj.mjOBJ_SITE, self.site, self._velocity, 0)
        # The hand's velocity where the object's centre is (a turning hand moves an object held off-centre).
        offset = data.xipos[body] - data.site_xpos[self.site]
        carried = self._velocity[3:] + np.cross(self._velocity[:3], offset)
        return float(np.linalg.norm(moving - carried))

    def not_held(self, name: str) -> str | None:
        """Why the object ``name`` is not held (which rule of :meth:`holds` fails, with its numbers), or None
        if it is."""
        touching = self.touching(name)
        if not all(touching):
            sides = [side for side, touches in zip(("first", "second"), touching, strict=True) if not touches]
            return f"the {' and '.join(sides)} side's finger pads do not touch it"
        slip = self.slip(name)
        if slip >= HELD_SPEED:
            return (
                f"both sides' finger pads touch it, but it slips: it moves {slip:.3f} m/s against the hand "
                f"(held below {HELD_SPEED} m/s)"
            )
        return None
