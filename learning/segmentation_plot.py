"""A picture of a segmentation: the hand speed over time with the found boundaries (and the ground truth).

People judge a segmentation at a glance from the speed profile: every reaching movement is a bump, holds
are flat, and a boundary belongs in the valleys between bumps.
"""

from __future__ import annotations

from pathlib import Path

from besman.learning.demonstration import Demonstration
from besman.learning.figures import plt, save_png
from besman.learning.segmentation import Segmentation


def plot_segmentation(demo: Demonstration, segmentation: Segmentation, path: str | Path) -> Path:
    """Writes a PNG of the segmented speed with the boundaries (solid) and any ground-truth boundaries of
    the demonstration (dashed)."""
    figure, axes = plt.subplots(figsize=(12, 3.5), layout="constrained")
    axes.plot(segmentation.signal_times, segmentation.speed, color="black", linewidth=1.0, label="hand speed")
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
