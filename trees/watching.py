"""Watching a run in the browser: the runner's observer that drives a :class:`~besman.sim.viewer.Viewer`.

After every tick it poses the 3D scene (the viewer sends a frame when one is due), writes the tree panel, and
paces the run at ``speed`` times real time, so that people can follow it (a run without a viewer goes as
fast as the machine allows).
"""

from __future__ import annotations

import time

from py_trees.common import Status

from besman.sim.viewer import Viewer
from besman.trees.runner import Runner


class Watch:
    """``Runner(..., observe=Watch(viewer))``: shows every tick and paces the run at ``speed`` x real time."""

    def __init__(self, viewer: Viewer, speed: float = 1.0) -> None:
        self.viewer, self.speed = viewer, speed
        self._start: tuple[float, float] | None = None  # (sim time, wall time) of the first tick

    def __call__(self, runner: Runner, record: dict) -> None:
        data = runner.executor.world.data
        if self._start is None:
            self._start = (data.time, time.perf_counter())
        # A frame when one is due, and always the run's last tick.
        self.viewer.show(data, force=runner.root.status is not Status.RUNNING)
        self.viewer.show_tree(record, list(runner.paths.values()))
        ahead = (data.time - self._start[0]) / self.speed - (time.perf_counter() - self._start[1])
        if ahead > 0:
            time.sleep(ahead)
