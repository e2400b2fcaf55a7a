"""A picture of a segmentation: the hand speed over time with the found boundaries (and the ground truth).

People judge a segmentation at a glance from the speed profile: every reaching movement is a bump, holds
are flat, and a boundary belongs in the valleys between bumps. Holds are shaded grey, and the segments in
which the contact signals say the hand holds the object (from the grip alone: the grip is steady) green.
"""

from __future__ import annotations

from pathlib import Path

from besman.learning.figures import plt, save_png
from besman.learning.segmentation.contact import OBJECT_SIGNAL
from besman.learning.segmentation.demonstration import Demonstration
from besman.learning.segmentation.segmenter import Segmentation


def plot_segmentation(demo: Demonstration, segmentation: Segmentation, path: str | Path) -> Path:
    """Writes a PNG of the segmented speed with the boundaries (solid) and any ground-truth boundaries of
    the demonstration (dashed)."""
    figure, axes = plt.subplots(figsize=(12, 3.5), layout="constrained")
    axes.plot(segmentation.signal_times, segmentation.speed, color="black", linewidth=1.0, label="hand speed")
    held = (
        "holding the object"
        if any(s.startswith(OBJECT_SIGNAL) for s in segmentation.signals)
        else "steady grip"
    )
    shaded = set()
    for k, (hold, holding) in enumerate(zip(segmentation.holds, segmentation.holding, strict=True)):
        for shown, color, label in ((hold, "0.85", "hold"), (holding, "tab:green", held)):
            if shown:
                axes.axvspan(
                    *segmentation.times[k : k + 2],
                    color=color,
                    alpha=0.3,
                    label=None if label in shaded else label,
                )
                shaded.add(label)
    for k, time in enumerate(segmentation.times):
        axes.axvline(time, color="tab:blue", linewidth=1.5, label="boundaries" if k == 0 else None)
    truth = [demo.times[demo.frame_index(frame)] for frame in demo.boundary_frames()]
    for k, time in enumerate(truth):
        axes.axvline(
            time, color="tab:orange", linestyle="--", linewidth=1.2, label="ground truth" if k == 0 else None
        )
    axes.set_xlabel("time (s)")
    axes.set_ylabel("speed (m/s)")
    axes.set_title(
        f"{Path(demo.source).name if demo.source else 'demonstration'}: {len(segmentation)} segments"
    )
    axes.legend(loc="upper right")
    return save_png(figure, path)
