"""Running a behaviour tree in lockstep with the simulation, and its JSON-lines log.

The :class:`Runner` ticks the tree at a fixed rate of simulated time (default 50 Hz); between ticks the
executor runs its control cycles (500 Hz) and the physics. It stops at SUCCESS, FAILURE or a sim-time
limit. Every tick is recorded: the status and feedback of every visited node (by its path in the tree),
the blackboard writes of that tick, and a summary of the robot and objects. The log is JSON lines:

- a header ``{"schema_version": 1, "kind": "besman-run-log", "run": {...}}`` (what was run, with which
  settings: enough to run it again),
- one line per tick ``{"tick", "time", "statuses", "feedback", "blackboard", "robot"}``,
- a result line ``{"result": {...}}``.

:func:`read_log` reads it back; :func:`statuses` gives the per-tick statuses of a run or a log, and
:func:`replay` runs a logged run again from its header, so the two can be compared.
"""

from __future__ import annotations

import json
import math
import time
from collections.abc import Iterator
from dataclasses import asdict, dataclass
from pathlib import Path
from typing import Any

import numpy as np
import py_trees
from py_trees.common import Status

from besman.sim.executor import Executor
from besman.skills import MovementPrimitive
from besman.skills.storage import write_atomically

SCHEMA_VERSION = 1


@dataclass(frozen=True)
class RunResult:
    """How a run ended."""

    status: str  # "SUCCESS" | "FAILURE"
    sim_time_s: float
    wall_time_s: float
    ticks: int
    failed_node: str | None
    message: str


def node_paths(root: py_trees.behaviour.Behaviour) -> dict[Any, str]:
    """A unique path per node ("root/child/grandchild", with [i] when siblings share a name)."""
    paths: dict[Any, str] = {}

    def visit(node, path):
        paths[node.id] = path
        names = [child.name for child in node.children]
        for index, child in enumerate(node.children):
            label = child.name if names.count(child.name) == 1 else f"{child.name}[{index}]"
            visit(child, f"{path}/{label}")

    visit(root, root.name)
    return paths


def _jsonable(value: Any) -> Any:
    """Blackboard values as JSON: arrays as lists, primitives by name, anything else by its repr."""
    if isinstance(value, MovementPrimitive):
        return {"primitive": value.name, "space": value.space}
    if isinstance(value, np.ndarray):
        return np.round(value, 6).tolist()
    if isinstance(value, float | int | str | bool) or value is None:
        return value if not (isinstance(value, float) and not math.isfinite(value)) else str(value)
    if isinstance(value, list | tuple):
        return [_jsonable(item) for item in value]
    return repr(value)


class Runner:
    """Ticks a tree in lockstep with the executor's simulation and records every tick.

    Args:
        root: the tree's root behaviour.
        executor: drives the simulated robot; given to every behaviour's ``setup``.
        rate: ticks per simulated second.
        max_sim_time: simulated seconds after which the run stops as a FAILURE.
        run_info: what to write in the log header (tree file, settings, seed).
    """

    def __init__(
        self,
        root: py_trees.behaviour.Behaviour,
        executor: Executor,
        *,
        rate: float = 50.0,
        max_sim_time: float = 120.0,
        run_info: dict | None = None,
    ) -> None:
        cycles = 1.0 / (rate * executor.config.control_period)
        if abs(cycles - round(cycles)) > 1e-9 or round(cycles) < 1:
            raise ValueError(
                f"rate {rate} Hz must divide the control rate {1 / executor.config.control_period:g} Hz"
            )
        self.root, self.executor, self.rate, self.max_sim_time = root, executor, rate, max_sim_time
        self.cycles_per_tick = round(cycles)
        self.run_info = dict(run_info or {})
        self.records: list[dict] = []
        self.tick_seconds: list[float] = []  # wall time of each tick of the tree
        self.record_seconds: list[float] = []  # wall time of recording each tick
        self.tree = py_trees.trees.BehaviourTree(root)
        self.paths = node_paths(root)

    def run(self) -> RunResult:
        """Runs to the end and returns the result (the records are in ``self.records``)."""
        py_trees.blackboard.Blackboard.enable_activity_stream(maximum_size=10000)
        self.tree.setup(executor=self.executor)
        start_sim, start_wall = self.executor.time, time.perf_counter()
        status = Status.RUNNING
        while status is Status.RUNNING:
            begin = time.perf_counter()
            self.tree.tick()
            middle = time.perf_counter()
            status = self.root.status
            self.records.append(self._record())
            self.tick_seconds.append(middle - begin)
            self.record_seconds.append(time.perf_counter() - middle)
            if status is not Status.RUNNING:
                break
            if self.executor.time - start_sim >= self.max_sim_time:
                self.root.stop(Status.INVALID)
                break
            for _ in range(self.cycles_per_tick):
                self.executor.tick()
        py_trees.blackboard.Blackboard.disable_activity_stream()
        failed, message = self._outcome(status)
        return RunResult(
            status.value if status in (Status.SUCCESS, Status.FAILURE) else "FAILURE",
            self.executor.time - start_sim,
            time.perf_counter() - start_wall,
            len(self.records),
            failed,
            message,
        )

    def _outcome(self, status: Status) -> tuple[str | None, str]:
        if status is Status.SUCCESS:
            return None, self.root.feedback_message or "succeeded"
        if status is not Status.FAILURE:
            return self.root.name, f"stopped at the sim-time limit of {self.max_sim_time:g} s"
        # The failure's origin: the deepest failed node of the last tick.
        failed = [node for node in self.root.iterate() if node.status is Status.FAILURE]
        tip = max(failed, key=lambda node: self.paths[node.id].count("/"), default=self.root)
        return self.paths[tip.id], tip.feedback_message

    def _record(self) -> dict:
        statuses, feedback = {}, {}
        for node in self.root.iterate():
            if node.status is not Status.INVALID:
                path = self.paths[node.id]
                statuses[path] = node.status.value
                if node.feedback_message:
                    feedback[path] = node.feedback_message
        stream = py_trees.blackboard.Blackboard.activity_stream
        changes = [
            {
                "key": item.key,
                "activity": item.activity_type,
                "client": item.client_name,
                "value": _jsonable(item.current_value),
            }
            for item in stream.data
            if item.activity_type in ("INITIALISED", "WRITE")
        ]
        stream.clear()
        world = self.executor.world
        robot = {
            "joints": np.round(self.executor.measured_position(), 5).tolist(),
            "gripper": round(float(self.executor.gripper_state[0]), 5) if self.executor.gripper else None,
            "objects": {
                name: np.round(world.object_pose(name).position, 5).tolist() for name in world.objects
            },
        }
        return {
            "tick": len(self.records),
            "time": round(self.executor.time, 6),
            "statuses": statuses,
            "feedback": feedback,
            "blackboard": changes,
            "robot": robot,
        }

    def write_log(self, path: str | Path, result: RunResult) -> Path:
        """Writes the JSON-lines log (atomically)."""
        lines = [
            json.dumps({"schema_version": SCHEMA_VERSION, "kind": "besman-run-log", "run": self.run_info})
        ]
        lines += [json.dumps(record) for record in self.records]
        lines.append(json.dumps({"result": asdict(result)}))
        return write_atomically(path, ("\n".join(lines) + "\n").encode("utf-8"))


def read_log(path: str | Path) -> tuple[dict, list[dict], dict]:
    """(header, tick records, result) of a run log; a ``ValueError`` names the file and line of a problem."""
    path = Path(path)
    try:
        text = path.read_text(encoding="utf-8")
    except FileNotFoundError:
        raise ValueError(f"{path}: no such file") from None
    lines = [line for line in text.splitlines() if line.strip()]
    records = []
    for number, line in enumerate(lines, 1):
        try:
            records.append(json.loads(line))
        except json.JSONDecodeError as error:
            raise ValueError(f"{path}:{number}: not JSON ({error})") from None
    if not records or records[0].get("kind") != "besman-run-log":
        raise ValueError(f"{path}:1: not a besman run log")
    if records[0].get("schema_version") != SCHEMA_VERSION:
        raise ValueError(f"{path}:1: schema_version {records[0].get('schema_version')!r} is not supported")
    if "result" not in records[-1]:
        raise ValueError(f"{path}:{len(lines)}: the log ends without a result (the run did not finish)")
    return records[0], records[1:-1], records[-1]["result"]


def statuses(records: list[dict]) -> Iterator[dict[str, str]]:
    """The per-tick node statuses of a run (``Runner.records``) or a log (``read_log(...)[1]``)."""
    return (record["statuses"] for record in records)


def pick_place_settings(values: dict[str, tuple[float, ...]], seed: int | None) -> dict[str, list[float]]:
    """The object and place positions of a tabletop run: given values (checked against the pick-and-place
    task's bounds) or, where missing, drawn uniformly from those bounds with ``seed``."""
    from besman.sim.pick_place import PICK_PLACE_BOUNDS

    bounds = PICK_PLACE_BOUNDS
    rng = np.random.default_rng(seed)
    draw = rng.uniform(bounds.low, bounds.high)
    settings = {name: [float(v) for v in value] for name, value in values.items()}
    for name, columns in (("object", slice(0, 2)), ("place", slice(2, 4))):
        if name in settings:
            if len(settings[name]) != 2:
                raise ValueError(f"--set {name}=x,y needs two numbers, got {settings[name]}")
            tau = draw.copy()
            tau[columns] = settings[name]
            bounds.check(tau)  # a value outside the box is rejected with its name
        else:
            settings[name] = draw[columns].tolist()
    return settings


def tabletop_run(
    tree: str | Path | py_trees.behaviour.Behaviour,
    values: dict[str, tuple[float, ...]] | None = None,
    *,
    seed: int | None = None,
    max_sim_time: float = 120.0,
) -> tuple[Runner, dict[str, list[float]]]:
    """A runner for a tree (a file, checked first, or a root behaviour) on AILA's tabletop, ready to run:
    the box stands at ``object`` and ``/task/<name>`` holds every value (``place`` is where the box
    should go)."""
    from besman.sim.executor import Executor
    from besman.sim.world import TABLE, tabletop_world
    from besman.trees.blackboard import set_task_values
    from besman.trees.files import describe, load_tree

    settings = pick_place_settings(dict(values or {}), seed)
    from_file = not isinstance(tree, py_trees.behaviour.Behaviour)
    root = load_tree(tree) if from_file else tree  # every file problem is reported before anything runs
    py_trees.blackboard.Blackboard.clear()
    world = tabletop_world()
    world.place_on("box", TABLE.name, *settings["object"])
    set_task_values(settings)
    run_info = {
        "tree": str(Path(tree).resolve()) if from_file else describe(root),
        "settings": settings,
        "seed": seed,
        "max_sim_time": max_sim_time,
    }
    return Runner(root, Executor(world), max_sim_time=max_sim_time, run_info=run_info), settings


def run_on_tabletop(
    tree: str | Path | py_trees.behaviour.Behaviour,
    values: dict[str, tuple[float, ...]] | None = None,
    *,
    seed: int | None = None,
    log: str | Path | None = None,
    max_sim_time: float = 120.0,
) -> dict:
    """Runs a tree on AILA's tabletop (:func:`tabletop_run`) and returns the summary: status, placement error
    measured in the simulation, simulated and wall time, ticks, failed node and message."""
    runner, settings = tabletop_run(tree, values, seed=seed, max_sim_time=max_sim_time)
    result = runner.run()
    box = runner.executor.world.object_pose("box").position
    if log is not None:
        runner.write_log(log, result)
    return {
        "status": result.status,
        "placement_error_m": float(np.linalg.norm(box[:2] - np.asarray(settings["place"]))),
        "sim_time_s": result.sim_time_s,
        "wall_time_s": result.wall_time_s,
        "ticks": result.ticks,
        "failed_node": result.failed_node,
        "message": result.message,
    }


def replay(path: str | Path) -> list[dict[str, str]]:
    """Runs a logged run again from its header; returns its per-tick statuses (to compare with the log's)."""
    from besman.trees.files import loads_tree

    header, _, _ = read_log(path)
    run = header["run"]
    settings = {name: tuple(value) for name, value in run["settings"].items()}
    tree = run["tree"]
    if isinstance(tree, dict):  # a tree built in code, logged in the file format
        tree = loads_tree(json.dumps({"besman_tree": 1, "root": tree}))
    runner, _ = tabletop_run(tree, settings, seed=run.get("seed"), max_sim_time=run["max_sim_time"])
    runner.run()
    return list(statuses(runner.records))
