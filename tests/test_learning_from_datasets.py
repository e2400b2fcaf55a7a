"""besman learn --demos DATASET: a robot's recorded episodes (a LeRobot dataset) as demonstrations, labelled
by the gripper's events, imitated in the robot's joint space, and the learned tree run on unseen tau."""

from __future__ import annotations

import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

from besman.datasets.reader import read_dataset
from besman.datasets.writer import DatasetSpec, DatasetWriter, Episode
from besman.learning.pipeline.dataset_demonstrations import TCP_NAMES, robot_recordings
from besman.learning.pipeline.labels import gripper_labels
from besman.learning.pipeline.record import LearnError
from besman.learning.segmentation.labelling import DemonstrationSegment
from besman.learning.segmentation.preprocessing import hand_pose
from besman.learning.segmentation.segmenter import segment
from besman.sim.executor import Executor
from besman.tasks import task
from besman.tasks.running import run

BLOCKS = task("pick-place").building_blocks("aila")


def record(root: Path, episodes: int, *more: str) -> Path:
    command = [sys.executable, "-m", "besman", "record", "pick-place", "--dataset", str(root)]
    subprocess.run([*command, "--episodes", str(episodes), *more], check=True, capture_output=True)
    return root


def learn_command(demos: Path, pool: Path) -> list[str]:
    """``besman learn`` from ``demos`` into ``pool`` with a small budget (2 training tasks, 8 rollouts)."""
    command = [sys.executable, "-m", "besman", "learn", "--demos", str(demos), "--out", str(pool)]
    return [*command, "--training-tasks", "2", "--budget", "8"]


@pytest.fixture(scope="module")
def two_episodes(tmp_path_factory) -> Path:
    return record(tmp_path_factory.mktemp("robot") / "dataset", 2)


@pytest.fixture(scope="module")
def arm():
    return Executor(BLOCKS.world(BLOCKS.centre)).arm


def test_an_episode_becomes_a_demonstration_of_the_hand_and_the_grip(two_episodes, arm):
    recordings = robot_recordings(two_episodes, arm, "pick-place")
    assert [r.name for r in recordings] == ["episode_0000", "episode_0001"]
    recording = recordings[0]
    demo, joints = recording.demo, recording.joints
    positions, orientations = hand_pose(demo, "Hand top", "Hand left", "Hand right")
    for k in (0, len(joints) // 2, len(joints) - 1):  # the virtual markers read back as the TCP's pose
        pose = arm.site_pose(joints[k])
        np.testing.assert_allclose(positions[k], pose.position, atol=1e-3)
        turned = 2 * np.arccos(min(1.0, abs(float(np.dot(orientations[k], pose.quaternion)))))
        assert np.degrees(turned) < 0.5
    aperture = np.linalg.norm(demo.channels["Thumb"] - demo.channels["Index"], axis=1)
    assert aperture.max() == pytest.approx(2 * arm.gripper.open, abs=1e-6)
    # The gripper closed once for long, on the box (it starts a little closed and opens in 0.1 s).
    edges = np.flatnonzero(np.diff(np.r_[0, recording.held.astype(int), 0]))
    lengths = (edges[1::2] - edges[::2]) / 50
    assert sum(lengths > 0.5) == 1 and sum(lengths) - lengths.max() < 0.2
    assert demo.times[1] - demo.times[0] == pytest.approx(1 / 50)


def test_the_gripper_events_label_the_blocks_before_during_and_after_the_grasp(two_episodes, arm):
    recording = robot_recordings(two_episodes, arm, "pick-place")[0]
    result = segment(recording.demo)  # noise-free fingers: the contact signal's noise is floored
    bounds = result.boundaries
    movements = [
        DemonstrationSegment(recording.demo, bounds[k], bounds[k + 1])
        for k, hold in enumerate(result.holds)
        if not hold
    ]
    names = gripper_labels(movements, recording.held)
    assert sorted(n for n in names if n != "other") == ["after", "before", "holding"]
    held = movements[names.index("holding")]
    assert recording.held[held.start : held.end + 1].mean() > 0.9
    before, after = movements[names.index("before")], movements[names.index("after")]
    assert before.end <= held.start and after.start >= held.end
    assert (
        recording.held[before.start : before.end + 1].mean() < 0.1 and not recording.held[after.end :].any()
    )


def end_effector_dataset(source: Path, target: Path, arm) -> Path:
    """``source``'s episodes with the tool-centre point's pose (forward kinematics) for the joints."""
    dataset = read_dataset(source)
    names = dataset.features["observation.state"]["names"]
    columns = [names.index(f"{joint}.pos") for joint in arm.joints]
    features = {
        k: dict(v) for k, v in dataset.features.items() if k in ("action", "observation.environment_state")
    }
    features["observation.state"] = {"dtype": "float32", "shape": [7], "names": list(TCP_NAMES)}
    with DatasetWriter(target, DatasetSpec(dataset.fps, features, dataset.info["robot_type"])) as writer:
        for index in range(len(dataset.episodes)):
            frames = dataset.frames(index)
            poses = [arm.site_pose(q) for q in frames["observation.state"][:, columns].astype(float)]
            frames["observation.state"] = np.array([np.r_[pose.position, pose.quaternion] for pose in poses])
            kept = {k: frames[k] for k in features}
            writer.append(Episode(dataset.episodes[index]["tasks"][0], kept, facts=dataset.facts(index)))
    return target


def test_an_end_effector_datasets_joints_are_found_by_inverse_kinematics(two_episodes, arm, tmp_path):
    recording = robot_recordings(end_effector_dataset(two_episodes, tmp_path / "ee", arm), arm, "pick-place")[
        0
    ]
    recorded = read_dataset(tmp_path / "ee").frames(0)["observation.state"]
    reached = np.array([arm.site_pose(q).position for q in recording.joints])
    assert np.abs(reached - recorded[:, :3]).max() < 1e-3  # float32 poses, IK within 1 mm


@pytest.mark.slow
def test_datasets_that_cannot_teach_the_robot_are_refused_naming_why(tmp_path, arm):
    ur5e = record(tmp_path / "ur5e", 2, "--robot", "ur5e")
    with pytest.raises(LearnError, match=r"recorded on 'ur5e', learned for aila; .* record on the robot"):
        robot_recordings(ur5e, arm, "pick-place")
    with pytest.raises(LearnError, match="0 successful episodes of stack; learning needs at least two"):
        robot_recordings(record(tmp_path / "aila", 2), arm, "stack")


@pytest.mark.slow
def test_a_tree_learned_from_fifteen_noisy_demonstrations_succeeds_on_unseen_tau(tmp_path):
    dataset = record(tmp_path / "demos", 15, "--perturb", "perception")  # seeds 0-14, IK-planned
    pool = tmp_path / "pool"
    learned = subprocess.run(
        learn_command(dataset, pool),
        capture_output=True,
        text=True,
    )
    assert learned.returncode == 0, learned.stderr
    assert "reach -> carry -> return (15 of 15 recordings" in learned.stdout
    successes = [run(tree=pool / "tree.yaml", seed=seed).success for seed in range(1000, 1030)]
    assert sum(successes) >= 27, successes  # >= 90 % of 30 tau none of the demonstrations had
    # The same demonstrations as an end-effector dataset: their joints by inverse kinematics.
    arm = Executor(BLOCKS.world(BLOCKS.centre)).arm
    end_effector = end_effector_dataset(dataset, tmp_path / "end_effector", arm)
    learned = subprocess.run(
        learn_command(end_effector, tmp_path / "pool_ee"), capture_output=True, text=True
    )
    assert learned.returncode == 0, learned.stderr
    successes = [
        run(tree=tmp_path / "pool_ee" / "tree.yaml", seed=seed).success for seed in range(1000, 1010)
    ]
    assert sum(successes) >= 9, successes
