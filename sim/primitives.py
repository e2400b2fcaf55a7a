"""Movement primitives for an arm, made from goals instead of demonstrations.

- :func:`point_to_point` - a joint-space DMP (no forcing term) from one configuration to another, slow
  enough for its quintic to stay within the velocity, acceleration and jerk limits.
- :func:`straight_line` - a joint-space DMP that moves the arm's site along a straight line at a
  constant orientation: inverse kinematics at knots along the line, imitated by the DMP.
- :func:`cartesian_point_to_point` - a Cartesian DMP of a site to a pose (the executor converts it).
- :func:`shaped` - a learned joint-space primitive moved to new end points, keeping its shape.
- :func:`top_down` - the orientation of a hand pointing down.
"""

from __future__ import annotations

import copy
import math
from typing import TYPE_CHECKING

import numpy as np
import ruckig

from besman.core.errors import InputError
from besman.sim.arm import Arm
from besman.sim.references import at_rest, started
from besman.skills import DMP, CartesianDMP, MovementPrimitive, quaternion
from besman.skills.transformation import minimum_jerk

if TYPE_CHECKING:
    from scipy.interpolate import CubicSpline

LIMIT_MARGIN = 1e-3  # rad: how close a shaped movement may come to a joint limit


def top_down(yaw: float) -> np.ndarray:
    """Quaternion (w, x, y, z) of a hand pointing down, fingers closing along (cos yaw, sin yaw, 0)."""
    closing = np.array([math.cos(yaw), math.sin(yaw), 0.0])
    approach = np.array([0.0, 0.0, -1.0])
    matrix = np.column_stack([np.cross(closing, approach), closing, approach])
    return quaternion.from_matrix(matrix)


def point_to_point(
    name: str, start: np.ndarray, goal: np.ndarray, arm: Arm, duration: float = 0.5
) -> MovementPrimitive:
    """A point-to-point joint-space DMP lasting at least ``duration`` and long enough for its quintic to stay
    within the speed, acceleration and jerk limits (peaks 1.875 d / T, 5.77 d / T^2 and 60 d / T^3 for a
    distance d)."""
    distance = np.abs(goal - start)
    needed = max(
        float(np.max(1.875 * distance / arm.max_velocity)),
        float(np.max(np.sqrt(5.774 * distance / arm.max_acceleration))),
        float(np.max(np.cbrt(60.0 * distance / arm.max_jerk))),
    )
    dmp = DMP(len(goal), execution_time=max(duration, 1.1 * needed), goal=goal)
    return _joint_primitive(dmp, name, arm)


def straight_line(
    name: str,
    start: np.ndarray,
    goal_position: np.ndarray,
    orientation: np.ndarray,
    arm: Arm,
    duration: float,
    knots: int = 8,
    stop_within: float | None = None,
) -> MovementPrimitive | None:
    """A joint-space DMP that moves the arm's site on a straight line from where the configuration
    ``start`` puts it to ``goal_position`` (constant ``orientation``): inverse kinematics at ``knots``
    points of a minimum-jerk profile, each solved from the previous, imitated by the DMP. The fit smooths
    the corner where a joint reaches its limit. None if a knot is out of reach.

    It lasts ``duration`` or longer: long enough for the joints to stay within their speed, acceleration and
    jerk limits, and with ``stop_within`` (m; a guarded move, which brakes when the hand touches something)
    for braking within the limits from anywhere on it to move the hand at most that far."""
    origin = arm.site_pose(start).position
    path = [start]
    for fraction in minimum_jerk(np.linspace(0.0, 1.0, knots))[1:]:
        result = arm.solve_ik(origin + fraction * (goal_position - origin), orientation, initial=path[-1])
        if not result.success:
            return None
        path.append(result.qpos)
    path = np.array(path)
    from scipy.interpolate import CubicSpline  # here, not with the module, which tree leaves import (0.4 s)

    # The path against time divided by the duration: its derivatives scale with duration^-order.
    unit = CubicSpline(np.linspace(0.0, 1.0, knots), path, axis=0, bc_type="clamped")
    duration = _long_enough(arm, unit, duration, stop_within)
    dense = np.linspace(0.0, duration, 10 * knots)
    dmp = DMP(arm.dofs).imitate(dense, unit(dense / duration))
    # A straight move starts and ends at rest, exactly at its knots.
    dmp.configure(start=path[0], goal=path[-1], start_velocity=0.0, start_acceleration=0.0, goal_velocity=0.0)
    return _joint_primitive(dmp, name, arm)


def _long_enough(arm: Arm, unit: CubicSpline, duration: float, stop_within: float | None) -> float:
    """The least duration from ``duration`` up for which the joint path ``unit`` (of time / duration) keeps
    within the limits (with the margin :func:`point_to_point` leaves) and, with ``stop_within``, stops
    within that distance of the hand from every point (growing by 10 % until it does)."""
    s = np.linspace(0.0, 1.0, 80)
    peaks = [np.abs(unit(s, order)).max(axis=0) for order in (1, 2, 3)]
    limits = (arm.max_velocity, arm.max_acceleration, arm.max_jerk)
    needed = max(
        float(np.max(peak / limit)) ** (1.0 / order)
        for order, (peak, limit) in enumerate(zip(peaks, limits, strict=True), 1)
    )
    duration = max(duration, 1.1 * needed)
    if stop_within is None:
        return duration
    positions, speeds, accelerations = unit(s), unit(s, 1), unit(s, 2)
    hand = arm.site_path(positions)
    while True:
        stops = stopping_positions(arm, positions, speeds / duration, accelerations / duration**2)
        if np.linalg.norm(arm.site_path(stops) - hand, axis=1).max() <= stop_within:
            return duration
        duration *= 1.1


def stopping_positions(arm: Arm, positions, velocities, accelerations) -> np.ndarray:
    """Where the arm comes to rest from each state (rows) braking within its limits: Ruckig's time-optimal
    stop of every joint on its own, as the executor brakes
    (:meth:`~besman.sim.streaming.JerkLimitedStream.brake`)."""
    otg, trajectory = ruckig.Ruckig(arm.dofs), ruckig.Trajectory(arm.dofs)
    inputs = ruckig.InputParameter(arm.dofs)
    inputs.control_interface = ruckig.ControlInterface.Velocity
    inputs.synchronization = ruckig.Synchronization.No
    inputs.max_velocity = arm.max_velocity.tolist()
    inputs.max_acceleration = arm.max_acceleration.tolist()
    inputs.max_jerk = arm.max_jerk.tolist()
    inputs.target_velocity = inputs.target_acceleration = [0.0] * arm.dofs
    stops = []
    for state in zip(
        positions,
        velocities,
        np.clip(accelerations, -arm.max_acceleration, arm.max_acceleration),
        strict=True,
    ):
        inputs.current_position, inputs.current_velocity, inputs.current_acceleration = (
            a.tolist() for a in state
        )
        otg.calculate(inputs, trajectory)
        stops.append(trajectory.at_time(trajectory.duration)[0])
    return np.array(stops)


def on_arm(shape: MovementPrimitive, arm: Arm) -> MovementPrimitive:
    """``shape`` for the joints ``arm`` drives: itself, or where it drives more joints (learned on a waist
    and an arm, run by the arm alone while the waist is held for the other arm) its dimensions of the
    arm's joints. The arm's joints follow the learned deviation as before; the left-out joints' share of
    the movement is the planner's end points' concern."""
    if shape.space != "joint" or shape.group is None or shape.group == arm.name:
        return shape
    robot = arm.world.robot
    joints = [joint for name in shape.group.split("+") for joint in robot.group(name).joints]
    if shape.dmp.n_dims != len(joints) or not set(arm.joints) <= set(joints):
        return shape  # not a superset of the arm's joints: shaped() says what it needs
    index = [joints.index(joint) for joint in arm.joints]
    primitive = copy.deepcopy(shape)
    dmp = primitive.dmp
    dmp.n_dims = len(index)
    for vector in ("scale", "start", "start_velocity", "start_acceleration", "goal", "goal_velocity"):
        setattr(dmp, vector, getattr(dmp, vector)[index].copy())
    dmp.weights = dmp.weights[index].copy()
    primitive.group = arm.name
    return primitive


def shaped(
    shape: MovementPrimitive, name: str, start: np.ndarray, goal: np.ndarray, arm: Arm
) -> MovementPrimitive:
    """A copy of the joint-space primitive ``shape`` from ``start`` to ``goal`` (at rest at both ends) with
    its own forcing term and duration: a learned movement between new end points. The DMP's trajectory is
    the direct movement between the end points plus the forcing term's response, which does not depend on
    them (:mod:`besman.skills.transformation`), so the learned deviation from the direct path is kept -
    except where it would take a joint out of its range (an end point at a limit, say): that joint keeps
    the largest share of its deviation that stays inside (the response is linear in its weights, so the
    share is exact)."""
    shape = on_arm(shape, arm)
    if shape.space != "joint" or shape.dmp.n_dims != arm.dofs:
        raise InputError(
            f"primitive {shape.name!r} must be a joint-space primitive of {arm.dofs} joints "
            f"({', '.join(arm.joints)}) to be shaped"
        )
    primitive = copy.deepcopy(shape)
    primitive.name = name
    dmp = primitive.dmp
    dmp.configure(start=start, start_velocity=0.0, start_acceleration=0.0, goal=goal, goal_velocity=0.0)
    _keep_in_range(dmp, arm)
    return primitive


def _keep_in_range(dmp: DMP, arm: Arm) -> None:
    """Scales each joint's forcing weights of ``dmp`` (configured between its end points, at rest at both)
    down to the largest share of its deviation from the direct path that keeps the joint
    :data:`LIMIT_MARGIN` inside its range as the executor runs it (:func:`~besman.sim.references.started`;
    the response is linear in its weights, so the share is exact)."""
    start, goal = dmp.start, dmp.goal
    direct = DMP(arm.dofs, execution_time=dmp.execution_time, dt=dmp.dt, start=start, goal=goal)
    path = direct.trajectory().positions
    # As executed from rest: the forcing term's start acceleration is taken out of the moving goal's there,
    # a term linear in the weights too.
    response = started(copy.deepcopy(dmp), at_rest(start), dmp.dt).positions - path
    room = np.where(response > 0, arm.upper - LIMIT_MARGIN - path, arm.lower + LIMIT_MARGIN - path)
    moves = np.abs(response) > 1e-12
    shares = np.ones(arm.dofs)
    for joint in range(arm.dofs):
        moving = moves[:, joint]
        if moving.any():
            share = (room[moving, joint] / response[moving, joint]).min()
            shares[joint] = min(1.0, max(0.0, share))
    dmp.weights = dmp.weights * shares[:, None]


def cartesian_point_to_point(
    name: str, position, orientation, duration: float, frame: str = "right_grasp"
) -> MovementPrimitive:
    """A Cartesian DMP (no forcing term) of ``frame`` to a position and orientation (w, x, y, z)."""
    dmp = CartesianDMP(execution_time=duration, goal_position=position, goal_orientation=orientation)
    return MovementPrimitive(dmp, name, space="cartesian", frame=frame)


def _joint_primitive(dmp: DMP, name: str, arm: Arm) -> MovementPrimitive:
    return MovementPrimitive(dmp, name, robot=arm.world.robot.name, group=arm.name)
