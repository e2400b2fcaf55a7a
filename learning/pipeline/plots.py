"""The figures :func:`besman.learning.pipeline.end_to_end.learn` writes beside the pool.

- ``segmentations.png``: each recording's hand speed, its segment boundaries, and the instances of the
  task's blocks shaded in their colours;
- ``learning_curves.png``: per block, the best reward so far over the rollouts of each training task;
- ``summary.png``: per block and training task, the retargeted primitive's reward before refinement and the
  refined one (filled: the rollout succeeded).
"""

from __future__ import annotations

from itertools import cycle
from pathlib import Path

import numpy as np

from besman.learning.figures import plt, save_png
from besman.learning.segmentation.demonstration import Demonstration
from besman.learning.segmentation.labelling import DemonstrationSegment
from besman.learning.segmentation.preprocessing import smooth

# The blocks' colours, in the task's order: matplotlib's tab colours but grey (the segment starts').
COLOURS = (
    "tab:blue",
    "tab:orange",
    "tab:green",
    "tab:red",
    "tab:purple",
    "tab:brown",
    "tab:pink",
    "tab:olive",
    "tab:cyan",
)


def write_figures(
    out: Path,
    demos: list[Demonstration],
    files: list[Path],
    movements: list[list[DemonstrationSegment]],
    instances: dict[str, list[dict]],
    refined: dict[str, list[dict]],
) -> tuple[Path, ...]:
    """The three figures in ``out``: the blocks' ``instances`` in the recordings and their ``refined``
    training tasks, each block (in the task's order, that of ``refined``) in its colour."""
    colours = dict(zip(refined, cycle(COLOURS)))
    return (
        _segmentations(out / "segmentations.png", demos, files, movements, instances, colours),
        _curves(out / "learning_curves.png", refined, colours),
        _summary(out / "summary.png", refined, colours),
    )


def _segmentations(path, demos, files, movements, instances, colours) -> Path:
    figure, axes = plt.subplots(len(demos), 1, figsize=(10, 1.1 * len(demos) + 0.8), squeeze=False)
    for row, (demo, file, per_demo) in enumerate(zip(demos, files, movements, strict=True)):
        ax = axes[row, 0]
        times = demo.times - demo.times[0]
        speed = np.linalg.norm(np.gradient(smooth(demo, "Hand top").positions, demo.times, axis=0), axis=1)
        ax.plot(times, speed, color="k", lw=0.8)
        for s in per_demo:
            ax.axvline(times[s.start], color="0.6", lw=0.5)
        for block, found in instances.items():
            for instance in found:
                if instance["file"] == file.name:
                    ax.axvspan(
                        times[instance["start"]], times[instance["end"]], color=colours[block], alpha=0.3
                    )
        ax.set_ylabel(file.stem, rotation=0, ha="right", fontsize=7)
        ax.set_yticks([])
    axes[-1, 0].set_xlabel(
        "time (s); hand speed, segment starts (grey), the blocks: "
        + ", ".join(f"{block} ({colour[4:]})" for block, colour in colours.items())
    )
    figure.suptitle("Segmentation and the instances of each building block")
    figure.tight_layout()
    return save_png(figure, path)


def _per_block(refined):
    """A figure with one panel per block, and the panels paired with the blocks' training runs."""
    figure, axes = plt.subplots(1, len(refined), figsize=(4 * len(refined), 3.2), squeeze=False)
    return figure, zip(axes[0], refined.items(), strict=True)


def _curves(path, refined, colours) -> Path:
    figure, panels = _per_block(refined)
    for ax, (block, runs) in panels:
        for run in runs:
            curve = np.array(run["curve"])
            ax.plot(curve[:, 0], curve[:, 2], color=colours[block], alpha=0.6, lw=1)
        ax.set_title(f"{block}: {len(runs)} training tasks")
        ax.set_xlabel("rollout")
        ax.set_ylabel("best reward so far")
    figure.tight_layout()
    return save_png(figure, path)


def _summary(path, refined, colours) -> Path:
    figure, panels = _per_block(refined)
    for ax, (block, runs) in panels:
        k = np.arange(len(runs))
        for offset, key, outcome, label in (
            (-0.15, "start_reward", "start_outcome", "retargeted"),
            (0.15, "reward", "outcome", "refined"),
        ):
            rewards = np.array([run[key] for run in runs])
            success = np.array([run[outcome]["success"] for run in runs])
            colour = colours[block] if key == "reward" else "0.5"
            ax.scatter(k[success] + offset, rewards[success], color=colour, label=label)
            ax.scatter(k[~success] + offset, rewards[~success], facecolors="none", edgecolors=colour)
        ax.set_title(block)
        ax.set_xlabel("training task")
        ax.set_ylabel("reward (filled: success)")
        ax.legend(fontsize=7)
    figure.suptitle("Before and after refinement by CMA-ES")
    figure.tight_layout()
    return save_png(figure, path)
