"""A gripper compiled against a model: opening in metres, whatever its actuator takes as command.

Grippers differ in what their actuators' commands mean: AILA's position actuator takes the opening of each
finger in metres, the Robotiq 2F-85's takes 0 (open) to 255 (closed) on a tendon over two driver joints, and
a gripper with an actuator per finger takes a position for each. Skills speak only of the opening - metres
per finger, half the aperture between the pads - and the description's table of matching openings and
commands (one column per actuator, measured on the model, see each robot's README) translates, piecewise
linearly, in both directions.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from besman.core.errors import InputError
from besman.robots.description import JointLimitSpec


@dataclass(frozen=True, eq=False)
class Gripper:
    """An arm's gripper in a compiled model.

    Attributes:
        group: the fingers' joint group (their velocities tell when the fingers have settled).
        actuators: indices of its actuators in ``MjData.ctrl``.
        opening, command: the description's matching table, sorted by opening (both read-only): openings
            (k,) and commands (k, actuators).
        open: the opening that grasps and releases (m per finger).
        pads: geom ids of each side's pads (a grasp needs both sides touching).
        limits: the opening's velocity, acceleration and jerk limits (m/s^k per finger).
        still_speed: the finger joints' speed (their units per s) under which closed fingers have settled.
    """

    group: str
    actuators: np.ndarray
    opening: np.ndarray
    command: np.ndarray
    open: float
    pads: tuple[np.ndarray, np.ndarray]
    limits: JointLimitSpec
    still_speed: float

    @property
    def lower(self) -> float:
        """The smallest opening the gripper is commanded to (m per finger)."""
        return float(self.opening[0])

    @property
    def upper(self) -> float:
        """The largest opening (m per finger)."""
        return float(self.opening[-1])

    def command_for(self, opening):
        """The actuators' commands that hold the fingers at ``opening`` (clipped to the table's range): one
        per actuator, along the last axis."""
        return np.stack([np.interp(opening, self.opening, column) for column in self.command.T], axis=-1)

    def opening_for(self, command):
        """The opening(s) that the first actuator's command(s) ``command`` hold (the others' follow the
        table)."""
        first = self.command[:, 0]
        order = np.argsort(first)
        return np.interp(command, first[order], self.opening[order])


def measure_openings(robot, arm: str | None, commands, settle: float = 3.0) -> np.ndarray:
    """The opening (m per finger) that each row of ``commands`` (one command per actuator) holds with
    nothing in the hand: from the
    robot's home keyframe the command is applied for ``settle`` s of simulated time, then the smallest
    distance between a pad of one side and a pad of the other (MuJoCo's ``mj_geomDistance``, exact for
    boxes and convex meshes) is halved. This is how each robot's opening/command table is made (its README
    cites the run)."""
    import mujoco

    arm = robot.arm(arm)
    gripper, model = arm.gripper, robot.model
    if gripper is None:
        raise InputError(f"robot {robot.name!r}: arm {arm.name!r} has no gripper")
    data = mujoco.MjData(model)
    openings = []
    for command in np.asarray(commands, dtype=float).reshape(-1, len(gripper.actuators)):
        robot.reset(data)
        data.ctrl[gripper.actuators] = command
        for _ in range(round(settle / model.opt.timestep)):
            mujoco.mj_step(model, data)
        gap = min(
            mujoco.mj_geomDistance(model, data, int(one), int(other), 1.0, None)
            for one in gripper.pads[0]
            for other in gripper.pads[1]
        )
        openings.append(max(gap, 0.0) / 2)  # touching pads press into each other a little: closed
    return np.array(openings)
