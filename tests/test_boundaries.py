"""Annotation conventions on a model's segments: minor movements folded, holds merged, turning points."""

import numpy as np

from besman.learning.segmentation.boundaries import fold_minor_movements, merge_holds, turning_points
from besman.learning.segmentation.changepoints import JointModel, SegmentModel

HOLD = JointModel.of(SegmentModel("still", degree=-1, hold=True))
MOVE = JointModel.of(SegmentModel("reach", degree=-1, bumps=((2.0, 2.0),)))
CARRY = JointModel("reach, holding", MOVE.parts, holding=True)


def bumps(*pieces: tuple[int, float]) -> np.ndarray:
    """A speed profile of bell-shaped movements: (samples, peak) each; a peak of 0 is a pause."""
    return np.concatenate([peak * np.sin(np.linspace(0, np.pi, n)) ** 2 for n, peak in pieces])


def test_a_minor_movement_next_to_a_hold_joins_the_pause_and_between_movements_disappears():
    speed = bumps((40, 0.0), (20, 0.1), (60, 1.0), (20, 0.05), (60, 0.8))
    boundaries = np.array([0, 40, 60, 120, 140, 200])
    folded, kept = fold_minor_movements(boundaries, [HOLD, MOVE, MOVE, MOVE, MOVE], speed)
    merged, kept = merge_holds(folded, kept)
    np.testing.assert_array_equal(merged, [0, 60, 140, 200])  # one pause; the 0.05 m/s wiggle is gone
    assert [m.hold for m in kept] == [True, False, False]
    start = bumps((15, 0.2), (60, 1.5), (30, 0.0))  # a twitch before the first reach
    folded, kept = fold_minor_movements(np.array([0, 15, 75, 105]), [MOVE, MOVE, HOLD], start)
    np.testing.assert_array_equal(folded, [0, 75, 105])
    slow = bumps((30, 0.0), (40, 0.1), (30, 0.0))  # a slow movement between two pauses is a movement
    folded, kept = fold_minor_movements(np.array([0, 30, 70, 100]), [HOLD, MOVE, HOLD], slow)
    np.testing.assert_array_equal(folded, [0, 30, 70, 100])


def test_between_movements_the_boundary_moves_to_the_slowest_sample_unless_the_contact_is_elsewhere():
    speed = bumps((50, 1.0), (50, 1.0))
    speed[40] = 0.0  # the slowest sample
    for boundary in (45, 52, 58):
        np.testing.assert_array_equal(
            turning_points(np.array([0, boundary, 100]), [MOVE, MOVE], speed, 60.0), [0, 40, 100]
        )
    # A grasp 0.1 s from the slowest sample is the same event; 0.3 s away, the contact decides.
    np.testing.assert_array_equal(
        turning_points(np.array([0, 46, 100]), [MOVE, CARRY], speed, 60.0), [0, 40, 100]
    )
    np.testing.assert_array_equal(
        turning_points(np.array([0, 58, 100]), [MOVE, CARRY], speed, 60.0), [0, 58, 100]
    )
    np.testing.assert_array_equal(
        turning_points(np.array([0, 45, 100]), [HOLD, MOVE], speed, 60.0), [0, 45, 100]
    )
