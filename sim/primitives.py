"""Movement primitives for a robot's executor, made from goals instead of demonstrations.

- :func:`point_to_point` - a joint-space DMP (no forcing term) from one configuration to another, slow
  enough for its quintic to stay within the velocity, acceleration and jerk limits.
- :func:`straight_line` - a joint-space DMP that moves the executor's site along a straight line at a
  constant orientation: inverse kinematics at knots along the line, imitated by the DMP.
- :func:`cartesian_point_to_point` - a Cartesian DMP of a site to a pose (the executor converts it).
- :func:`top_down` - the orientation of a hand pointing down.
"""

from __future__ import annotations

import math

import mujoco
import numpy as np
from scipy.interpolate import CubicSpline

import besman.robots as robots
from besman.sim.executor import Executor
from besman.skills import DMP, CartesianDMP, MovementPrimitive


def top_down(yaw: float) -> np.ndarray:
    """Quaternion (w, x, y, z) of a hand pointing down, fingers closing along (cos yaw, sin yaw, 0)."""
    closing = np.array([math.cos(yaw), math.sin(yaw), 0.0])
    approach = np.array([0.0, 0.0, -1.0])
    matrix = np.column_stack([np.cross(closing, approach), closing, approach])
    quaternion = np.empty(4)
    mujoco.mju_mat2Quat(quaternion, matrix.ravel())
    return quaternion


def point_to_point(
    name: str, start: np.ndarray, goal: np.ndarray, executor: Executor, duration: float = 0.5
) -> MovementPrimitive:
    """A point-to-point joint-space DMP lasting at least ``duration`` and long enough for its quintic to stay
    within the speed, acceleration and jerk limits (peaks 1.875 d / T, 5.77 d / T^2 and 60 d / T^3 for a
    distance d)."""
    distance = np.abs(goal - start)
    needed = max(
        float(np.max(1.875 * distance / executor.max_velocity)),
        float(np.max(np.sqrt(5.774 * distance / executor.max_acceleration))),
        float(np.max(np.cbrt(60.0 * distance / executor.max_jerk))),
    )
    dmp = DMP(len(goal), execution_time=max(duration, 1.1 * needed), goal=goal)
    return MovementPrimitive(dmp, name, robot=executor.world.robot.name, group="+".join(executor.groups))


def straight_line(
    name: str,
    start: np.ndarray,
    goal_position: np.ndarray,
    orientation: np.ndarray,
    executor: Executor,
    duration: float,
    knots: int = 8,
) -> MovementPrimitive | None:
    """A joint-space DMP that moves the executor's site on a straight line from where the configuration
    ``start`` puts it to ``goal_position`` (constant ``orientation``): inverse kinematics at ``knots``
    points of a minimum-jerk profile, each solved from the previous, imitated by the DMP. The fit smooths
    the corner where a joint reaches its limit. None if a knot is out of reach."""
    origin = robots.forward_kinematics(
        executor.world.robot, executor.full_qpos(start), executor.site
    ).position
    times = np.linspace(0.0, duration, knots)
    s = times / duration
    profile = 10 * s**3 - 15 * s**4 + 6 * s**5
    path = [start]
    for fraction in profile[1:]:
        result = executor.solve_ik(
            origin + fraction * (goal_position - origin), orientation, initial=path[-1]
        )
        if not result.success:
            return None
        path.append(result.qpos)
    path = np.array(path)
    dense = np.linspace(0.0, duration, 10 * knots)
    positions = CubicSpline(times, path, axis=0, bc_type="clamped")(dense)
    dmp = DMP(executor.dofs, dt=executor.config.control_period).imitate(dense, positions)
    # A straight move starts and ends at rest, exactly at its knots.
    dmp.configure(start=path[0], goal=path[-1], start_velocity=0.0, start_acceleration=0.0, goal_velocity=0.0)
    return MovementPrimitive(dmp, name, robot=executor.world.robot.name, group="+".join(executor.groups))


def cartesian_point_to_point(
    name: str, position, orientation, duration: float, frame: str = "right_grasp"
) -> MovementPrimitive:
    """A Cartesian DMP (no forcing term) of ``frame`` to a position and orientation (w, x, y, z)."""
    dmp = CartesianDMP(execution_time=duration, goal_position=position, goal_orientation=orientation)
    return MovementPrimitive(dmp, name, space="cartesian", frame=frame)
