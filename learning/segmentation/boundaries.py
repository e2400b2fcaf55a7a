"""Where people draw boundaries: a change-point model's segments turned into annotated-style ones.

The change points of :mod:`besman.learning.segmentation.changepoints` are where the signal's statistics
change; people who annotate recordings of manipulation draw boundaries by other conventions, and these
functions apply them, in this order:

1. :func:`fold_minor_movements`: a movement much slower than its neighbours (adjusting a grasp, a twitch at
   rest) is no building block;
2. :func:`merge_holds`: consecutive pauses are one pause;
3. :func:`movement_onsets`: where a movement meets a pause, the boundary is the movement's onset or offset at
   a fraction of its peak speed (the convention of human reaching studies);
4. :func:`turning_points`: between two movements, the boundary is where the hand is slowest, unless the
   contact signals put a grasp or a release clearly elsewhere.

All work on sample indices of the hand's speed at the recording's own rate.
"""

from __future__ import annotations

import numpy as np

from besman.core.errors import InputError
from besman.learning.segmentation.changepoints import JointModel

# A movement slower than this fraction of a neighbouring movement's peak speed is no building block: on the
# shared recordings, reaches and carries peak at 0.5-2 m/s, grasp adjustments and twitches at 0.05-0.3 m/s.
MINOR_MOVEMENT = 0.2
# A speed minimum this close to a change of contact (s) is the same event: the fingers close as the hand
# stops, or open as it starts back.
CONTACT_SNAP = 0.2


def fold_minor_movements(
    boundaries: np.ndarray, models: list[JointModel], speed: np.ndarray
) -> tuple[np.ndarray, list[JointModel]]:
    """Movements whose peak speed is below :data:`MINOR_MOVEMENT` x the peak of a neighbouring movement
    folded into their neighbours: next to a hold they become part of the pause (fingers and wrist adjusting
    a grasp), between movements (or at either end of the recording) the neighbouring movement takes them
    over. They are real motion, but no building block: a reach's or a carry's peak speed is several times
    theirs. ``boundaries`` are sample indices of ``speed``."""
    boundaries, models = list(boundaries), list(models)
    peaks = [float(speed[boundaries[j] : boundaries[j + 1]].max()) for j in range(len(models))]
    k = 0
    while k < len(models) and len(models) > 1:
        neighbours = [j for j in (k - 1, k + 1) if 0 <= j < len(models)]
        moving = [peaks[j] for j in neighbours if not models[j].hold]
        if models[k].hold or not moving or peaks[k] >= MINOR_MOVEMENT * max(moving):
            k += 1
            continue
        holds = [j for j in neighbours if models[j].hold]
        if holds:
            models[k] = models[holds[0]]  # part of the pause: merged with it below
            k += 1
        else:  # the neighbouring movements meet in it (the boundary moves to their turning point later)
            taker = k + 1 if k == 0 else k - 1
            peaks[taker] = max(peaks[taker], peaks[k])
            del boundaries[k + 1 if k == 0 else k], models[k], peaks[k]
    return np.array(boundaries), models


def merge_holds(boundaries: np.ndarray, models: list[JointModel]) -> tuple[np.ndarray, list[JointModel]]:
    """Consecutive holds as one (a pause is one pause, whatever the fingers do in it)."""
    keep = [0] + [k for k in range(1, len(models)) if not (models[k].hold and models[k - 1].hold)]
    return np.r_[boundaries[keep], boundaries[-1]], [models[k] for k in keep]


def turning_points(
    boundaries: np.ndarray, models: list[JointModel], speed: np.ndarray, rate: float
) -> np.ndarray:
    """Boundaries between two movements moved to the speed minimum between the two movements' peaks: without
    a pause, the hand turns from one movement into the next where it is slowest, and people who annotate
    recordings draw the boundary there. Where the contact changes (the hand grasps or lets go without
    pausing), the slowest point counts only within :data:`CONTACT_SNAP` of the change; farther away, the
    boundary stays where the contact signals put it. ``boundaries`` are sample indices of ``speed``, sampled
    at ``rate`` (Hz)."""
    moved = np.array(boundaries)
    snap = CONTACT_SNAP * rate
    for k in range(1, len(models)):
        before, after = models[k - 1], models[k]
        if before.hold or after.hold:
            continue
        first = boundaries[k - 1] + int(np.argmax(speed[boundaries[k - 1] : boundaries[k]]))
        second = boundaries[k] + int(np.argmax(speed[boundaries[k] : boundaries[k + 1]]))
        slowest = first + int(np.argmin(speed[first : second + 1]))
        if before.holding == after.holding or abs(slowest - boundaries[k]) <= snap:
            moved[k] = slowest
    return moved


def movement_onsets(
    boundaries: np.ndarray, holds: tuple[bool, ...], speed: np.ndarray, fraction: float
) -> np.ndarray:
    """Boundaries between holds and movements moved to the movement's onset and offset: the first sample at
    which its speed reaches ``fraction`` x its peak after a hold, the first below it before a hold (the usual
    definition in studies of human reaching, with 5-10 % of the peak speed; people annotating recordings
    see a movement begin there, not where it becomes statistically distinguishable from a hold).
    ``boundaries`` are sample indices of ``speed``; a hold keeps at least one sample."""
    if not 0.0 < fraction < 1.0:
        raise InputError(
            f"the onset threshold must be a fraction of the peak speed in (0, 1), got {fraction!r}"
        )
    moved = np.array(boundaries)
    for k, hold in enumerate(holds):
        if hold:
            continue
        start, end = boundaries[k], boundaries[k + 1]
        peak = start + int(np.argmax(speed[start:end]))
        slow = speed < fraction * speed[peak]
        if k > 0 and holds[k - 1]:
            before = np.flatnonzero(slow[boundaries[k - 1] + 1 : peak])
            if len(before):
                moved[k] = boundaries[k - 1] + 1 + before[-1] + 1
        if k + 1 < len(holds) and holds[k + 1]:
            after = np.flatnonzero(slow[peak : boundaries[k + 2]])
            if len(after):
                moved[k + 1] = peak + after[0]
    return moved
