"""A robot's demonstrations from a LeRobot dataset (:mod:`besman.datasets.reader`), for ``besman learn
--demos DATASET``: each successful episode as a
:class:`~besman.learning.segmentation.demonstration.Demonstration` that the pipeline segments and labels as it
does a person's, with what a robot's recording has and a person's has not - its joints, and the gripper's
events:

- the hand: the tool-centre point's pose by forward kinematics of the measured joints (the dataset's
  ``observation.state`` names ``<joint>.pos`` for every joint of the arm) or, in an end-effector dataset,
  as recorded (``tcp.x`` ... ``tcp.qz``; its joints by inverse kinematics), as three virtual hand markers
  that :func:`~besman.learning.segmentation.preprocessing.hand_pose` reads back as that pose (left - right
  along the TCP's y, the top along its x, their centroid at the TCP);
- the grip: two markers ("Thumb", "Index") apart by twice the commanded opening (the action's
  ``<arm>.gripper``) along the TCP's y - the grip aperture that segmentation observes as its contact signal;
- holding: the gripper commanded closed from its open opening (task structure's holding, where a person's
  recording has the object's marker, and the labels: the blocks before the grasp, holding, after the
  release).

No retargeting: the dataset's robot must be the one learned for (``robot_type``); the blocks are imitated in
its joint space (:func:`besman.learning.pipeline.refinement.joint_shapes`).
"""

from __future__ import annotations

import hashlib
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from besman.datasets.reader import DatasetError, read_dataset
from besman.learning.pipeline.imitation import HAND_MARKERS
from besman.learning.pipeline.record import LearnError
from besman.learning.segmentation.demonstration import Demonstration

MARKER_SPACING = 0.03  # m: the virtual markers' distance from the tool-centre point
# An end-effector dataset's pose of the tool-centre point in observation.state (m, world frame; a unit
# quaternion w, x, y, z): its joints are found by inverse kinematics, within IK_TOLERANCE (m, rad).
TCP_NAMES = ("tcp.x", "tcp.y", "tcp.z", "tcp.qw", "tcp.qx", "tcp.qy", "tcp.qz")
IK_TOLERANCE = (1e-3, 1e-2)
CLOSED_MARGIN = 0.002  # m: commanded this far below its open opening, the gripper is closing or closed


@dataclass(frozen=True, eq=False)
class RobotRecording:
    """One episode as learning reads it: its ``name`` (as a recording's file name), the checksum of its
    frames, the demonstration, the arm's measured ``joints`` (T, dofs) and ``held`` (T,): the gripper
    commanded closed."""

    name: str
    checksum: str
    demo: Demonstration
    joints: np.ndarray
    held: np.ndarray


def robot_recordings(path: str | Path, arm, task: str) -> list[RobotRecording]:
    """The dataset's successful episodes of ``task`` recorded on ``arm``'s robot, checked (the robot, the
    arm's joints and its gripper among the features) before anything is learned."""
    try:
        dataset = read_dataset(path)
    except DatasetError as error:
        raise LearnError(str(error)) from None
    robot = arm.world.robot.name
    if dataset.info.get("robot_type") != robot:
        raise LearnError(
            f"{path}: recorded on {dataset.info.get('robot_type')!r}, learned for {robot}; learning from "
            "another robot's dataset would need retargeting between the two: record on the robot learned for"
        )
    state = list(dataset.features.get("observation.state", {}).get("names") or [])
    actions = list(dataset.features.get("action", {}).get("names") or [])
    joint_names = [f"{joint}.pos" for joint in arm.joints]
    wanted = joint_names if all(name in state for name in joint_names) else list(TCP_NAMES)
    gripper = next((i for i, name in enumerate(actions) if name.endswith(".gripper")), None)
    if any(name not in state for name in wanted) or gripper is None:
        raise LearnError(
            f"{path}: observation.state needs the arm's joints ({', '.join(joint_names)}) or the tool-centre "
            f"point's pose ({', '.join(TCP_NAMES)}), and action a <arm>.gripper column (the gripper's events "
            "are the contact signal)"
        )
    columns = [state.index(name) for name in wanted]
    opened = arm.gripper.open
    found = []
    for index in range(len(dataset.episodes)):
        facts = dataset.facts(index)
        if facts.get("besman/success") is False or facts.get("besman/task", task) != task:
            continue  # a failed run, or another task's, teaches nothing of this one
        frames = dataset.frames(index)
        recorded = frames["observation.state"][:, columns].astype(float)
        joints = recorded if wanted == joint_names else _joints_of(arm, recorded, f"{path}: episode {index}")
        opening = frames["action"][:, gripper].astype(float)
        digest = hashlib.sha256(joints.tobytes() + opening.tobytes()).hexdigest()
        demo = _demonstration(arm, joints, opening, frames["frame_index"], dataset.fps, f"{path}#{index}")
        found.append(
            RobotRecording(f"episode_{index:04d}", digest, demo, joints, opening < opened - CLOSED_MARGIN)
        )
    if len(found) < 2:
        raise LearnError(f"{path}: {len(found)} successful episodes of {task}; learning needs at least two")
    return found


def _joints_of(arm, poses: np.ndarray, where: str) -> np.ndarray:
    """The arm's joints along a recorded path of the tool-centre point ((T, 7): x, y, z, qw, qx, qy, qz), by
    inverse kinematics from the previous sample's (the first from the arm's home); an error names the first
    sample the arm cannot reach."""
    joints, previous = np.empty((len(poses), arm.dofs)), arm.home
    for k, pose in enumerate(poses):
        result = arm.solve_ik(pose[:3], pose[3:], initial=previous)
        if result.position_error > IK_TOLERANCE[0] or result.orientation_error > IK_TOLERANCE[1]:
            raise LearnError(
                f"{where}: the arm cannot reach the recorded pose of sample {k} ({result.message})"
            )
        joints[k] = previous = result.qpos
    return joints


def _demonstration(arm, joints, opening, frame_index, fps: int, source: str) -> Demonstration:
    poses = [arm.site_pose(q) for q in joints]
    positions = np.array([pose.position for pose in poses])
    rotations = np.array([pose.rotation for pose in poses])
    x, y = rotations[:, :, 0], rotations[:, :, 1]
    base = positions - MARKER_SPACING / 3 * x  # the three markers' centroid at the TCP
    top, left, right = HAND_MARKERS
    channels = {
        top: base + MARKER_SPACING * x,
        left: base + MARKER_SPACING * y,
        right: base - MARKER_SPACING * y,
        "Thumb": positions + opening[:, None] * y,
        "Index": positions - opening[:, None] * y,
    }
    frames = np.asarray(frame_index, dtype=int)
    return Demonstration(frames / float(fps), frames, channels, source=source)
