"""Labelling segments into building blocks and imitating each block by a Cartesian DMP."""

import numpy as np
import pytest

from besman.learning import (
    Demonstration,
    DemonstrationSegment,
    Segment,
    cluster,
    ground_truth_segments,
    grouping_accuracy,
    imitate,
    label_few_shot,
    load,
    segments_of,
)
from besman.learning.segmentation.demonstration import PICK_AND_PLACE_MAIN_SEGMENTS
from besman.learning.segmentation.segmenter import segment
from besman.skills.primitive import MovementPrimitive
from besman.skills.transformation import minimum_jerk

RATE = 60.0
HOLD = 36  # samples (0.6 s) of rest before each movement
WAYPOINTS = {"reach": [0.5, -0.2, 0.9], "carry": [0.5, 0.3, 1.1], "return": [0.2, 0.0, 0.8]}


def pick_and_place(seed: int, hand_markers: bool = True) -> Demonstration:
    """Three minimum-jerk movements between perturbed waypoints, short holds, with annotated segments; the
    hand is a rigid triangle of three markers turning about z during the carry."""
    rng = np.random.default_rng(seed)
    position, orientation = np.array([0.2, 0.0, 0.8]), 0.0
    pieces, angles, segments, frame = [], [], [], 100
    for label, waypoint in WAYPOINTS.items():
        pieces.append(np.repeat(position[None], HOLD, axis=0))
        angles.append(np.full(HOLD, orientation))
        samples = round(rng.uniform(0.8, 1.2) * RATE)
        s = np.arange(samples + 1) / samples
        blend = minimum_jerk(s)
        target = np.asarray(waypoint) + rng.normal(0, 0.02, 3)
        turn = 0.6 if label == "carry" else -orientation
        pieces.append(position + blend[:, None] * (target - position))
        angles.append(orientation + blend * turn)
        start = frame + HOLD + sum(map(len, pieces[:-2]))
        segments.append(Segment(start, start + samples, label))
        position, orientation = target, orientation + turn
    hand = np.concatenate(pieces)
    angle = np.concatenate(angles)
    channels = {"Hand top": hand}
    if hand_markers:
        offsets = {"Hand left": np.array([0.0, 0.04, 0.0]), "Hand right": np.array([0.0, -0.04, 0.0])}
        for name, offset in offsets.items():
            rotated = np.column_stack(
                [-np.sin(angle) * offset[1], np.cos(angle) * offset[1], np.zeros_like(angle)]
            )
            channels[name] = hand + rotated - np.array([0.0, 0.0, 0.03])
    channels = {name: values + rng.normal(0, 0.0002, values.shape) for name, values in channels.items()}
    frames = np.arange(frame, frame + len(hand))
    return Demonstration(
        frames / RATE, frames, channels, source=f"synthetic{seed}.tsv", segments=tuple(segments)
    )


def test_building_blocks_are_grouped_without_labels_and_from_one_labelled_demonstration():
    demos = [pick_and_place(seed) for seed in range(6)]
    segments = [s for demo in demos for s in ground_truth_segments(demo)]
    labels = [s.label for s in segments]
    assert len(segments) == 18 and labels[:3] == ["reach", "carry", "return"]
    assert grouping_accuracy(labels, cluster(segments, 3)) == 1.0
    rest = [s for demo in demos[1:] for s in ground_truth_segments(demo)]
    assert label_few_shot(ground_truth_segments(demos[0]), rest) == [s.label for s in rest]


def test_grouping_accuracy_matches_groups_to_labels_optimally():
    assert grouping_accuracy(list("aabbcc"), [2, 2, 0, 0, 1, 1]) == 1.0
    assert grouping_accuracy(list("aabbcc"), [0, 0, 0, 0, 1, 1]) == pytest.approx(4 / 6)


def test_labelling_errors_are_clear():
    demo = pick_and_place(0)
    segments = ground_truth_segments(demo)
    with pytest.raises(ValueError, match="3 segments cannot form 4 building blocks"):
        cluster(segments, 4)
    unlabelled = [DemonstrationSegment(demo, s.start, s.end) for s in segments]
    with pytest.raises(ValueError, match=r"the labelled examples \[0, 1, 2\] have no label"):
        label_few_shot(unlabelled, segments)
    with pytest.raises(ValueError, match="too short to describe"):
        cluster([DemonstrationSegment(demo, 5, 6), *segments], 2)


def test_segmentation_feeds_labelling():
    demo = pick_and_place(3)
    segmentation = segment(demo)
    found = segments_of(demo, segmentation)
    moving = [s for s, hold in zip(found, segmentation.holds, strict=True) if not hold]
    assert len(moving) == 3
    for found_segment, true_segment in zip(moving, ground_truth_segments(demo), strict=True):
        assert (
            abs(found_segment.start - true_segment.start) <= 6
            and abs(found_segment.end - true_segment.end) <= 6
        )


def test_each_building_block_becomes_a_cartesian_primitive_of_its_mean_instance(tmp_path):
    demos = [pick_and_place(seed) for seed in range(4)]
    carries = [ground_truth_segments(demo, ["carry"])[0] for demo in demos]
    primitive = imitate(carries, name="carry")
    assert primitive.space == "cartesian" and primitive.frame == "motion capture world"
    assert primitive.provenance["units"] == "m" and len(primitive.provenance["instances"]) == 4
    assert primitive.provenance["instances"][0]["source"] == "synthetic0.tsv"
    trajectory = primitive.dmp.trajectory()
    ends = [
        np.mean([demo.channels[name][s.end] for name in ("Hand top", "Hand left", "Hand right")], axis=0)
        for demo, s in zip(demos, carries, strict=True)
    ]
    np.testing.assert_allclose(trajectory.positions[-1], np.mean(ends, axis=0), atol=0.003)
    assert primitive.dmp.execution_time == pytest.approx(np.mean([s.duration for s in carries]), rel=1e-6)
    # The hand turns by 0.6 rad about z during the carry.
    q0, q1 = trajectory.orientations[0], trajectory.orientations[-1]
    turn = 2 * np.arccos(np.clip(abs(np.dot(q0, q1)), -1, 1))
    assert turn == pytest.approx(0.6, abs=0.03)
    loaded = MovementPrimitive.load(primitive.save(tmp_path / "carry"))
    assert loaded.provenance == primitive.provenance
    single = imitate(
        [ground_truth_segments(pick_and_place(0, hand_markers=False), ["reach"])[0]], name="reach"
    )
    np.testing.assert_allclose(
        single.dmp.trajectory().orientations,
        np.tile([1.0, 0, 0, 0], (len(single.dmp.trajectory().orientations), 1)),
        atol=1e-9,
    )
    with pytest.raises(ValueError, match="building block 'none' has no segments"):
        imitate([], name="none")


@pytest.mark.slow
def test_the_main_segments_of_the_shared_recordings_are_grouped(shared_recordings):
    """Measured: 100 % unsupervised; few-shot 1-NN 98.7 % on average over the labelled demonstration (the
    issue asks 95 %), 89 % in the worst case (one subject's run labelled, the other subject's classified)."""
    per_demo = [
        ground_truth_segments(load(path), PICK_AND_PLACE_MAIN_SEGMENTS)
        for path in sorted(shared_recordings.glob("*.tsv"))
    ]
    segments = [s for demo in per_demo for s in demo]
    assert len(segments) == 90
    assert grouping_accuracy([s.label for s in segments], cluster(segments, 6)) >= 0.99
    accuracies = []
    for k, labelled in enumerate(per_demo):
        rest = [s for j, demo in enumerate(per_demo) if j != k for s in demo]
        predicted = label_few_shot(labelled, rest)
        accuracies.append(np.mean([p == s.label for p, s in zip(predicted, rest, strict=True)]))
    assert np.mean(accuracies) >= 0.95
