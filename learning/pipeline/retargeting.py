"""Retargeting: a person's movement, imitated as a Cartesian primitive, becomes a movement of AILA's arm.

Two steps, each documented by what it keeps:

1. **Workspace map** (:class:`WorkspaceMap`): a similarity transform from the motion-capture frame into the
   robot's world frame, p_robot = s R_z(yaw) p_human + offset. Both frames have z up (the capture's z:
   on the shared recordings the "Back top" marker is 5-6 cm above "Back left/right"), so the map rotates
   about the vertical only; one scale keeps the movement's shape (angles and proportions). It is fitted on
   two correspondences (:func:`fit_workspace_map`): where the person's hand ends the reach (the object on
   their table) and where it ends the carry (the place), onto the robot's hand poses above the object and
   above the place for the middle task of the pick-and-place bounds. The horizontal vector between the two
   fixes yaw and scale; the offset puts the person's grasp point on the robot's. On the shared
   recordings the person's grasp-to-place vector is about 0.78 m long, AILA's 0.34 m: the person's
   movements shrink to about 0.44 of their size.
2. **Onto the arm** (:func:`retarget`): the person's movement (the imitated primitive's trajectory) minus
   the direct movement between its end points (a DMP without forcing, at rest at both ends) is its shape;
   the map's linear part A = s R_z(yaw) maps that deviation. The robot's movement is its direct joint-space
   movement from the block's start to its end configuration with the hand displaced by the person's
   mapped deviation at every instant: inverse kinematics from the direct movement's configuration (within
   :data:`SHAPE_TOLERANCE`), keeping the direct movement's hand orientation (a person's hand and a parallel
   gripper hold objects differently, so the hand's orientation is not copied). A joint-space DMP of the
   arm imitates it and ends in the planned configuration: a primitive that
   :func:`besman.sim.primitives.shaped` moves to any other end points of the block, shape and all.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from besman.core.errors import InputError
from besman.sim.arm import Arm
from besman.skills import DMP, CartesianDMP, MovementPrimitive
from besman.skills.dmp_core import DMPSettings

# How closely the arm must follow the mapped path: it is the shape of a movement (its end points are the
# planned configurations), and near a joint limit (AILA's home pose has a wrist joint at one) inverse
# kinematics may fall short by millimetres.
SHAPE_TOLERANCE = (0.02, 0.2)  # m, rad


@dataclass(frozen=True)
class WorkspaceMap:
    """p_robot = scale * R_z(yaw) p_human + offset (positions in m, yaw in rad)."""

    yaw: float
    scale: float
    offset: tuple[float, float, float]

    @property
    def linear(self) -> np.ndarray:
        c, s = math.cos(self.yaw), math.sin(self.yaw)
        return self.scale * np.array([[c, -s, 0.0], [s, c, 0.0], [0.0, 0.0, 1.0]])

    def apply(self, points) -> np.ndarray:
        """Robot-frame positions of human-frame positions (..., 3)."""
        return np.asarray(points, dtype=float) @ self.linear.T + np.asarray(self.offset)

    def as_dict(self) -> dict:
        return {
            "form": "p_robot = scale * R_z(yaw) p_human + offset",
            "yaw_degrees": math.degrees(self.yaw),
            "scale": self.scale,
            "offset_m": list(self.offset),
        }


def fit_workspace_map(human_grasp, human_place, robot_grasp, robot_place) -> WorkspaceMap:
    """The map that sends the person's grasp point onto the robot's and the horizontal direction and length
    from grasp to place onto the robot's (see the module documentation)."""
    human_grasp, human_place, robot_grasp, robot_place = (
        np.asarray(p, dtype=float) for p in (human_grasp, human_place, robot_grasp, robot_place)
    )
    human = complex(*(human_place - human_grasp)[:2])
    robot = complex(*(robot_place - robot_grasp)[:2])
    if abs(human) < 0.05:
        raise InputError(
            f"the demonstrations' grasp and place points are {abs(human) * 100:.1f} cm apart horizontally: "
            "too close to fit the workspace map (the reach and the carry must end in different places)"
        )
    ratio = robot / human
    partial = WorkspaceMap(math.atan2(ratio.imag, ratio.real), abs(ratio), (0.0, 0.0, 0.0))
    offset = robot_grasp - partial.apply(human_grasp)
    return WorkspaceMap(partial.yaw, partial.scale, tuple(float(v) for v in offset))


def retarget(
    primitive: MovementPrimitive,
    mapping: WorkspaceMap,
    arm: Arm,
    start: np.ndarray,
    goal: np.ndarray,
    *,
    n_weights: int = 6,
) -> MovementPrimitive:
    """The joint-space primitive of ``arm`` from the configuration ``start`` to ``goal`` whose hand deviates
    from the direct movement as the person's hand does in the Cartesian ``primitive`` (mapped by
    ``mapping``); see the module documentation. Raises an :class:`~besman.core.errors.InputError` naming
    the time if the arm cannot follow."""
    if not isinstance(primitive.dmp, CartesianDMP):
        raise InputError(f"primitive {primitive.name!r} is not Cartesian: retargeting maps hand paths")
    # The person's deviation from the direct movement between the same end points (at rest at both, as the
    # robot's movements are), mapped by A.
    human = primitive.dmp.trajectory()
    duration, period = primitive.dmp.execution_time, primitive.dmp.dt
    straight = DMP(3, execution_time=duration, dt=period, start=human.positions[0], goal=human.positions[-1])
    offsets = (human.positions - straight.trajectory().positions) @ mapping.linear.T
    direct = DMP(arm.dofs, execution_time=duration, dt=period, start=start, goal=goal)
    joints = direct.trajectory().positions.copy()
    for k, (configuration, offset) in enumerate(zip(joints, offsets, strict=True)):
        pose = arm.site_pose(configuration)
        result = arm.solve_ik(
            pose.position + offset, pose.quaternion, initial=configuration, tolerances=(1e-7, 1e-6)
        )
        if result.position_error > SHAPE_TOLERANCE[0] or result.orientation_error > SHAPE_TOLERANCE[1]:
            raise InputError(
                f"retargeting {primitive.name!r}: AILA's hand cannot follow the path at "
                f"t={human.times[k]:.2f} s ({np.round(pose.position + offset, 3).tolist()}): "
                f"{result.message}"
            )
        joints[k] = np.clip(result.qpos, arm.lower, arm.upper)
    joint_dmp = DMP(arm.dofs, settings=DMPSettings(n_weights=n_weights), execution_time=direct.execution_time)
    # The primitive will start and end at rest (``shaped``): imitate it under those boundary conditions, so
    # that the forcing term, not a start acceleration estimated from the path, carries the shape.
    velocities = np.gradient(joints, human.times, axis=0, edge_order=2)
    velocities[[0, -1]] = 0.0
    accelerations = np.gradient(velocities, human.times, axis=0, edge_order=2)
    accelerations[[0, -1]] = 0.0
    joint_dmp.imitate(human.times, joints, velocities=velocities, accelerations=accelerations)
    joint_dmp.configure(start=start, goal=goal, start_velocity=0.0, start_acceleration=0.0, goal_velocity=0.0)
    return MovementPrimitive(
        joint_dmp,
        primitive.name,
        robot=arm.world.robot.name,
        group=arm.name,
        provenance={
            **primitive.provenance,
            "retargeting": {
                "map": mapping.as_dict(),
                "path": "the direct joint-space movement plus the person's mapped deviation from theirs",
                "orientation": "the direct movement's (not the person's hand orientation)",
                "joint_weights_per_joint": n_weights,
            },
        },
    )
