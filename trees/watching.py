"""Watching runs in the browser (:class:`~besman.sim.viewer.Viewer`): live, and replayed from their logs.

- :class:`Watch` - the runner's observer: after every tick it poses the 3D scene (the viewer sends a frame
  when one is due), writes the tree panel, and paces the run at ``speed`` times real time, so that people
  can follow it (a run without a viewer goes as fast as the machine allows).
- :class:`Replay` - a run's JSON-lines log on a timeline: scene and tree panel of any tick.
"""

from __future__ import annotations

import json
import threading
import time
from collections.abc import Callable
from pathlib import Path

import mujoco
import py_trees
from py_trees.common import Status

from besman.core.errors import InputError
from besman.sim.executor import Executor
from besman.sim.overlays import template_spread
from besman.sim.viewer import Viewer, within
from besman.trees.base import RoleBehaviour
from besman.trees.leaves import InstantiateSkillTemplate
from besman.trees.runner import Runner, jsonable, object_addresses, read_log


def shown(value) -> str:
    """A blackboard value as the tree panel shows it: compact JSON."""
    return json.dumps(jsonable(value), separators=(",", ":"))


def describe_node(node: py_trees.behaviour.Behaviour, status: str, feedback: str) -> str:
    """A node's details (markdown): its type and what it is for, status, parameters and blackboard keys."""
    kind = type(node)
    lines = [f"**{node.name}** (`{kind.__name__}`): {(kind.__doc__ or '').strip().splitlines()[0]}"]
    lines.append(f"status {status}{': ' + feedback if feedback else ''}")
    parameters = {
        name: getattr(node, name) for name in getattr(kind, "parameters", {}) if hasattr(node, name)
    }
    if parameters:
        lines.append(
            "parameters: " + ", ".join(f"{name} = {shown(value)[:60]}" for name, value in parameters.items())
        )
    if isinstance(node, RoleBehaviour):
        keys = node.role_keys(node.namespace, node.remap)
        lines.append(
            "blackboard: "
            + ", ".join(f"{role} `{key}` ({node.roles[role].name.lower()})" for role, key in keys.items())
        )
    return "  \n".join(lines)


class Watch:
    """``Runner(..., observe=Watch(viewer))``: shows every tick and paces the run at ``speed`` x real time.

    A frame (when one is due, and always the run's last tick) poses the scene and the overlays
    (:mod:`besman.sim.overlays`: the motion's planned and executed hand paths, target frames, objects) and
    writes the tree panel with the blackboard's values and the active motion. A template instantiated in a
    tick (an :class:`~besman.trees.leaves.InstantiateSkillTemplate` that succeeded) shows its spread.
    """

    def __init__(self, viewer: Viewer, speed: float = 1.0) -> None:
        self.viewer, self.speed = viewer, speed
        self._start: tuple[float, float] | None = None  # (sim time, wall time) of the first tick
        self._runner: Runner | None = None
        self._instantiating: list[InstantiateSkillTemplate] = []  # the runner's template leaves
        self._instances: dict = {}  # per instantiating leaf: the (template, tau) last shown

    def restart_pacing(self) -> None:
        """Paces from the next tick on (after a pause, the run does not race to catch up)."""
        self._start = None

    def __call__(self, runner: Runner, record: dict) -> None:
        executor, viewer = runner.executor, self.viewer
        data = executor.world.data
        overlays = viewer.overlays_for(executor.arm)
        if self._runner is not runner:
            self._runner, nodes = runner, {path: node for node, path in runner.nodes}
            self._instantiating = [
                node for node in nodes.values() if isinstance(node, InstantiateSkillTemplate)
            ]
            viewer.set_nodes(
                list(nodes),
                lambda path: describe_node(
                    nodes[path], nodes[path].status.value, nodes[path].feedback_message
                ),
            )
        if self._start is None:
            self._start = (data.time, time.perf_counter())
        for node in self._instantiating:
            if self._instances.get(node.id) is not node.instantiated:
                self._instances[node.id] = node.instantiated
                template, tau = node.instantiated
                overlays.show_spread(template_spread(executor.arm, template, tau, executor.stream.state()))
        overlays.follow(executor.motion)
        final = runner.root.status is not Status.RUNNING
        if viewer.show(data, force=final):
            overlays.update(data, final=final)
            viewer.show_tree(record, list(runner.paths.values()), self._values(executor))
        ahead = (data.time - self._start[0]) / self.speed - (time.perf_counter() - self._start[1])
        if ahead > 0:
            time.sleep(ahead)

    @staticmethod
    def _values(executor) -> dict[str, str]:
        values = {key: shown(value) for key, value in sorted(py_trees.blackboard.Blackboard.storage.items())}
        motion = executor.motion
        if motion is not None:
            values["active motion"] = f"{motion.name} ({motion.status.value})"
        return values


class Replay:
    """A logged run in the viewer: the scene and the tree panel of any tick, chosen on a timeline slider or
    played at the run's own pace (the log is :func:`~besman.trees.runner.read_log`'s; the scene is the
    one ``executor_of(header)`` rebuilds, the task's that made the log
    (:func:`besman.tasks.running.executor_of`), posed from each tick's ``robot`` record: every arm, hand and
    free body)."""

    def __init__(
        self, log: str | Path, executor_of: Callable[[dict], Executor], viewer_options: dict | None = None
    ) -> None:
        header, self.records, self.result = read_log(log)
        if not self.records:
            raise InputError(f"{log}: the log has no ticks to replay")
        self.nodes = header["run"].get("nodes") or list(
            dict.fromkeys(k for r in self.records for k in r["statuses"])
        )
        executor = executor_of(header)
        self.world = executor.world
        self._arm = executor.arm.qpos_indices
        self._fingers = None if executor.hand is None else executor.hand.fingers.qpos_indices
        self._arms = {  # the other arms of the run: joints and fingers
            name: (arm.arm.qpos_indices, None if arm.hand is None else arm.hand.fingers.qpos_indices)
            for name, arm in executor.companions.items()
        }
        self._objects = object_addresses(self.world)
        self._tick = 0
        # Per tick, the blackboard as it stood (every key's last write); per node, the ticks that visited it.
        self._values, self._visits, values = [], {}, {}
        for record in self.records:
            values.update((change["key"], json.dumps(change["value"])) for change in record["blackboard"])
            self._values.append(dict(sorted(values.items())))
            for path in record["statuses"]:
                self._visits.setdefault(path, []).append(record["tick"])
        self.viewer = Viewer(self.world.model, **(viewer_options or {}))
        gui = self.viewer.server.gui
        with gui.add_folder("Replay"):
            self.slider = gui.add_slider("tick", min=0, max=len(self.records) - 1, step=1, initial_value=0)
            self.play = gui.add_checkbox("play", initial_value=False)
        self.viewer.set_nodes(self.nodes, self._describe)
        self.slider.on_update(lambda _: self.show(int(within(self.slider))))
        self._closed = threading.Event()
        self._player = threading.Thread(target=self._play, daemon=True)
        self._player.start()
        self.show(0)

    def show(self, tick: int) -> None:
        """Poses the scene and writes the tree panel as they were at ``tick``."""
        record = self.records[tick]
        robot, qpos = record["robot"], self.world.data.qpos
        qpos[self._arm] = robot["joints"]
        if robot.get("fingers") is not None and self._fingers is not None:
            qpos[self._fingers] = robot["fingers"]
        for name, arm in robot.get("arms", {}).items():
            if name in self._arms:
                joints, fingers = self._arms[name]
                qpos[joints] = arm["joints"]
                if arm["fingers"] is not None and fingers is not None:
                    qpos[fingers] = arm["fingers"]
        for name, pose in robot["objects"].items():
            if name in self._objects and len(pose) == 7:
                qpos[self._objects[name] : self._objects[name] + 7] = pose
        mujoco.mj_kinematics(self.world.model, self.world.data)
        self.viewer.show(self.world.data, force=True)
        self._tick = tick
        self.viewer.show_tree(record, self.nodes, self._values[tick])

    def _describe(self, path: str) -> str:
        """A node's details in the log: its status and feedback at the shown tick, and when it was visited."""
        record = self.records[self._tick]
        visited = self._visits.get(path, [])
        status, feedback = record["statuses"].get(path, "INVALID"), record["feedback"].get(path, "")
        lines = [
            f"**{path.rsplit('/', 1)[-1]}** (`{path}`)",
            f"status {status}{': ' + feedback if feedback else ''}",
        ]
        if visited:
            lines.append(f"visited in {len(visited)} ticks, {visited[0]} to {visited[-1]}")
        return "  \n".join(lines)

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
