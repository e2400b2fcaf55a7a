"""Imitation: one movement primitive per building block, learned from all of its instances at once.

The hand's pose (centroid and orientation of the three hand markers, Kalman/RTS-smoothed; the position of
one marker with a fixed orientation when a recording has no hand markers) over each instance is fitted by a
single Cartesian DMP (``CartesianDMP.imitate`` with several demonstrations: one ridge regression in which each
instance weighs the same, so the primitive is their mean shape, with mean start, goal and duration). The
primitive records where it came from: files, frames, units and the frame of its coordinates.
"""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np

from besman.core.errors import InputError
from besman.core.validation import checked, integer, positive, text
from besman.learning.segmentation.demonstration import Demonstration
from besman.learning.segmentation.labelling import SEGMENTS, DemonstrationSegment
from besman.learning.segmentation.preprocessing import hand_pose, smooth
from besman.skills.cartesian_dmp import CartesianDMP
from besman.skills.dmp_core import DMPSettings
from besman.skills.primitive import MovementPrimitive

HAND_MARKERS = ("Hand top", "Hand left", "Hand right")
IDENTITY = np.array([1.0, 0.0, 0.0, 0.0])


def _pose(demo: Demonstration, marker: str) -> tuple[np.ndarray, np.ndarray, str]:
    if all(name in demo.channels for name in HAND_MARKERS):
        positions, orientations = hand_pose(demo, *HAND_MARKERS)
        return positions, orientations, "centroid and orientation of Hand top, Hand left, Hand right"
    positions = smooth(demo, marker).positions
    return positions, np.tile(IDENTITY, (len(positions), 1)), f"position of {marker}, fixed orientation"


@checked(
    segments=SEGMENTS,
    name=text("a primitive name"),
    marker=text("a marker name"),
    n_weights=integer(2),
    dt=positive,
)
def imitate(
    segments: Sequence[DemonstrationSegment],
    *,
    name: str,
    marker: str = "Hand top",
    n_weights: int = 10,
    dt: float = 0.01,
) -> MovementPrimitive:
    """A Cartesian-DMP primitive ``name`` imitating all ``segments`` (instances of one building block)."""
    if not segments:
        raise InputError(f"building block {name!r} has no segments to imitate")
    poses: dict[int, tuple[np.ndarray, np.ndarray, str]] = {}
    times, positions, orientations, instances = [], [], [], []
    for segment in segments:
        key = id(segment.demo)
        if key not in poses:
            poses[key] = _pose(segment.demo, marker)
        position, orientation, what = poses[key]
        window = slice(segment.start, segment.end + 1)
        times.append(segment.demo.times[window])
        positions.append(position[window])
        orientations.append(orientation[window])
        instances.append(
            {
                "source": segment.demo.source,
                "start_frame": int(segment.demo.frames[segment.start]),
                "end_frame": int(segment.demo.frames[segment.end]),
                "label": segment.label,
            }
        )
    dmp = CartesianDMP(settings=DMPSettings(n_weights=n_weights), dt=dt).imitate(
        times, positions, orientations
    )
    units = {segment.demo.units for segment in segments}
    provenance = {
        "learner": "besman.learning.pipeline.imitation.imitate",
        "pose": what,
        "units": "m" if units == {"m"} else sorted(units),
        "instances": instances,
    }
    return MovementPrimitive(
        dmp, name, space="cartesian", frame="motion capture world", provenance=provenance
    )
