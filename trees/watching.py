"""Watching runs in the browser (:class:`~besman.sim.viewer.Viewer`): live, and replayed from their logs.

- :class:`Watch` - the runner's observer: after every tick it poses the 3D scene (the viewer sends a frame
  when one is due), writes the tree panel, and paces the run at ``speed`` times real time, so that people
  can follow it (a run without a viewer goes as fast as the machine allows).
- :class:`Replay` - a run's JSON-lines log on a timeline: scene and tree panel of any tick.
"""

from __future__ import annotations

import threading
import time
from pathlib import Path

import mujoco
from py_trees.common import Status

from besman.sim.executor import Executor
from besman.sim.viewer import Viewer
from besman.sim.world import tabletop_world
from besman.skills.errors import InputError
from besman.trees.runner import Runner, object_addresses, read_log


class Watch:
    """``Runner(..., observe=Watch(viewer))``: shows every tick and paces the run at ``speed`` x real time."""

    def __init__(self, viewer: Viewer, speed: float = 1.0) -> None:
        self.viewer, self.speed = viewer, speed
        self._start: tuple[float, float] | None = None  # (sim time, wall time) of the first tick

    def restart_pacing(self) -> None:
        """Paces from the next tick on (after a pause, the run does not race to catch up)."""
        self._start = None

    def __call__(self, runner: Runner, record: dict) -> None:
        data = runner.executor.world.data
        if self._start is None:
            self._start = (data.time, time.perf_counter())
        # A frame when one is due, and always the run's last tick; the tree panel with every frame (every tick
        # at real-time pace; a faster run's ticks are all in its log).
        if self.viewer.show(data, force=runner.root.status is not Status.RUNNING):
            self.viewer.show_tree(record, list(runner.paths.values()))
        ahead = (data.time - self._start[0]) / self.speed - (time.perf_counter() - self._start[1])
        if ahead > 0:
            time.sleep(ahead)


class Replay:
    """A logged run in the viewer: the scene and the tree panel of any tick, chosen on a timeline slider or
    played at the run's own pace (the log is :func:`~besman.trees.runner.read_log`'s; the scene is AILA's
    tabletop, posed from each tick's ``robot`` record)."""

    def __init__(self, log: str | Path, viewer_options: dict | None = None) -> None:
        header, self.records, self.result = read_log(log)
        if not self.records:
            raise InputError(f"{log}: the log has no ticks to replay")
        self.nodes = header["run"].get("nodes") or list(
            dict.fromkeys(k for r in self.records for k in r["statuses"])
        )
        self.world = tabletop_world()
        executor = Executor(self.world)  # the arm and hand the run drove (the tabletop's defaults)
        self._arm = executor.arm.qpos_indices
        self._fingers = executor.hand.gripper.qpos_indices
        self._objects = object_addresses(self.world)
        self.viewer = Viewer(self.world.model, **(viewer_options or {}))
        gui = self.viewer.server.gui
        with gui.add_folder("Replay"):
            self.slider = gui.add_slider("tick", min=0, max=len(self.records) - 1, step=1, initial_value=0)
            self.play = gui.add_checkbox("play", initial_value=False)
        self.slider.on_update(lambda _: self.show(int(self.slider.value)))
        self._closed = threading.Event()
        self._player = threading.Thread(target=self._play, daemon=True)
        self._player.start()
        self.show(0)

    def show(self, tick: int) -> None:
        """Poses the scene and writes the tree panel as they were at ``tick``."""
        record = self.records[tick]
        robot, qpos = record["robot"], self.world.data.qpos
        qpos[self._arm] = robot["joints"]
        if robot.get("fingers") is not None:
            qpos[self._fingers] = robot["fingers"]
        for name, pose in robot["objects"].items():
            if name in self._objects and len(pose) == 7:
                qpos[self._objects[name] : self._objects[name] + 7] = pose
        mujoco.mj_kinematics(self.world.model, self.world.data)
        self.viewer.show(self.world.data, force=True)
        self.viewer.show_tree(record, self.nodes)

    @property
    def url(self) -> str:
        return self.viewer.url

    def close(self) -> None:
        self._closed.set()
        self._player.join()
        self.viewer.close()

    def _play(self) -> None:
        """While "play" is ticked, advance the slider at the run's pace (loops at the end)."""
        while not self._closed.is_set():
            if not self.play.value:
                self._closed.wait(0.05)
                continue
            tick = int(self.slider.value)
            following = (tick + 1) % len(self.records)
            pause = self.records[following]["time"] - self.records[tick]["time"]
            if not self._closed.wait(pause if 0 < pause < 1 else 0.02):
                self.slider.value = following  # its update handler shows the tick
