"""besman learn --demos DATASET: a robot's recorded episodes (a LeRobot dataset) as demonstrations, labelled
by the gripper's events, imitated in the robot's joint space, and the learned tree run on unseen tau."""

from __future__ import annotations

import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

from besman.learning.dataset_demonstrations import robot_recordings
from besman.learning.labelling import DemonstrationSegment
from besman.learning.pipeline_labels import gripper_labels
from besman.learning.pipeline_record import LearnError
from besman.learning.preprocessing import hand_pose
from besman.learning.segmentation import segment
from besman.sim.executor import Executor
from besman.tasks import task
from besman.tasks.running import run

BLOCKS = task("pick-place").building_blocks("aila")


def record(root: Path, episodes: int, *more: str) -> Path:
    command = [sys.executable, "-m", "besman", "record", "pick-place", "--dataset", str(root)]
    subprocess.run([*command, "--episodes", str(episodes), *more], check=True, capture_output=True)
    return root


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
        [
            sys.executable,
            "-m",
            "besman",
            "learn",
            "--demos",
            str(dataset),
            "--out",
            str(pool),
            "--tasks",
            "2",
            "--budget",
            "8",
        ],
        capture_output=True,
        text=True,
    )
    assert learned.returncode == 0, learned.stderr
    assert "reach -> carry -> return (15 of 15 recordings" in learned.stdout
    successes = [run(tree=pool / "tree.yaml", seed=seed).success for seed in range(1000, 1030)]
    assert sum(successes) >= 27, successes  # >= 90 % of 30 tau none of the demonstrations had
