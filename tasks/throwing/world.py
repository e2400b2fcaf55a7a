"""The throwing task's world: the PA-10 on a floor with its ball welded in its hand, and sensors of where the
ball is and whether it touches the robot."""

from __future__ import annotations

import mujoco

import besman.robots as robots
from besman.sim.world import World


def throwing_world() -> World:
    """The PA-10 scene: the arm on a floor with the ball welded in its hand."""
    pa10 = robots.describe("pa10")
    spec = robots.build_spec(pa10)
    spec.add_sensor(
        name="ball_position",
        type=mujoco.mjtSensor.mjSENS_FRAMEPOS,
        objtype=mujoco.mjtObj.mjOBJ_XBODY,
        objname="ball",
    )
    # How many contacts the ball has with the robot (the subtree of its base), every step.
    touch = spec.add_sensor(
        name="ball_touches_robot",
        type=mujoco.mjtSensor.mjSENS_CONTACT,
        objtype=mujoco.mjtObj.mjOBJ_BODY,
        objname="ball",
        reftype=mujoco.mjtObj.mjOBJ_XBODY,
        refname="base_link",
    )
    touch.intprm[:3] = [1, 0, 1]  # data "found", no reduction, one slot
    return World(pa10, spec)
