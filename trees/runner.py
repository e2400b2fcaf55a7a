"""Running a behaviour tree in lockstep with the simulation, and its JSON-lines log.

The :class:`Runner` ticks the tree at a fixed rate of simulated time (default 50 Hz); between ticks the
executor runs its control cycles (500 Hz) and the physics. It stops at SUCCESS, FAILURE or a sim-time
limit. Every tick is recorded: the status and feedback of every visited node (by its path in the tree),
the blackboard writes of that tick, and a summary of the robot and objects. The log is JSON lines:

- a header ``{"schema_version": 1, "kind": "besman-run-log", "run": {...}}`` (what was run, with which
  settings: enough to run it again; and ``nodes``, the tree's node paths in order),
- one line per tick ``{"tick", "time", "statuses", "feedback", "blackboard", "robot"}`` (``robot``: the arm's
  joints, the gripper command, the finger joints, each free body's position and orientation, and the joints
  and fingers of any other arm driven in lockstep (``arms``): what a replay needs to pose the scene),
- a result line ``{"result": {...}}`` (status SUCCESS, FAILURE, or INTERRUPTED for a run stopped by Ctrl-C).

With a log file, the runner writes it as the run goes (:class:`LogStream`), and the file appears, whole,
when the run ends or is interrupted.

:func:`read_log` reads it back and :func:`statuses` gives the per-tick statuses of a run or a log. The
runner knows nothing of any particular task: :mod:`besman.tasks.running` sets a task's runs up.
"""

from __future__ import annotations

import contextlib
import io
import json
import math
import os
import time
from collections import Counter
from collections.abc import Callable, Iterator
from dataclasses import asdict, dataclass
from pathlib import Path
from typing import Any, NoReturn

import mujoco
import numpy as np
import py_trees
from py_trees.common import Status

from besman.core.errors import InputError
from besman.core.reading import Limit, read_bytes
from besman.core.storage import (
    check_replaceable,
    check_schema_version,
    json_value,
    open_temporary,
    put_in_place,
    remove_temporaries,
    write_error,
)
from besman.core.validation import CALLABLE, COUNT, PATH, checked, instance, optional, positive
from besman.core.writer_lock import WriterLock
from besman.sim.executor import Executor
from besman.skills import MovementPrimitive
from besman.trees.base import BEHAVIOUR

SCHEMA_VERSION = 1
LOG_KIND = "besman-run-log"  # the header's kind: an earlier run log is all that --log replaces
# Run logs are refused above this size: a log takes about 140 kB a simulated second (the grasp-then-place
# demo's), so this holds some 15 minutes of a run; reading one takes about 2.5 times its size in memory.
LOG_LIMIT = Limit(128_000_000, "BESMAN_MAX_LOG_BYTES")
_STATUS_NAMES = {status: status.value for status in Status}  # an Enum's .value is a slow descriptor


@dataclass(frozen=True)
class RunResult:
    """How a run ended."""

    status: str  # "SUCCESS" | "FAILURE"
    sim_time_s: float
    wall_time_s: float
    ticks: int
    failed_node: str | None
    message: str
    # The first failure a Retry absorbed, "path: message", where the run then failed elsewhere: the fault a
    # later failure (of the retry) would hide.
    first_failure: str | None = None


def node_paths(root: py_trees.behaviour.Behaviour) -> dict[Any, str]:
    """A unique path per node ("root/child/grandchild", with [i] when siblings share a name), parents before
    their children in the tree's order."""
    paths: dict[Any, str] = {}

    pending = [(root, root.name)]  # a stack, not recursion: any depth, linear time; depth-first order
    while pending:
        node, path = pending.pop()
        paths[node.id] = path
        names = Counter(child.name for child in node.children)
        labelled = [
            (child, child.name if names[child.name] == 1 else f"{child.name}[{index}]")
            for index, child in enumerate(node.children)
        ]
        pending.extend((child, f"{path}/{label}") for child, label in reversed(labelled))
    return paths


def object_addresses(world) -> dict[str, int]:
    """Where each free body's pose (position, then w-x-y-z orientation) sits in ``qpos``, by body name: the
    world's objects, and anything else that flies free (the PA-10's ball)."""
    model = world.model
    free = np.flatnonzero(model.jnt_type == mujoco.mjtJoint.mjJNT_FREE)
    return {model.body(model.jnt_bodyid[j]).name: int(model.jnt_qposadr[j]) for j in free}


def jsonable(value: Any) -> Any:
    """Blackboard values as JSON: arrays as lists, primitives by name, anything else by its repr."""
    if isinstance(value, MovementPrimitive):
        return {"primitive": value.name, "space": value.space}
    if isinstance(value, np.ndarray):
        return np.round(value, 6).tolist()
    if isinstance(value, float | int | str | bool) or value is None:
        return value if not (isinstance(value, float) and not math.isfinite(value)) else str(value)
    if isinstance(value, list | tuple):
        return [jsonable(item) for item in value]
    return repr(value)


class Runner:
    """Ticks a tree in lockstep with the executor's simulation and records every tick.

    Args:
        root: the tree's root behaviour.
        executor: drives the simulated robot; given to every behaviour's ``setup``.
        rate: ticks per simulated second.
        max_sim_time: simulated seconds after which the run stops as a FAILURE.
        run_info: what to write in the log header (tree file, settings, seed).
        observe: called after every tick with the runner and the tick's record (e.g. a viewer).
    """

    @checked(
        root=BEHAVIOUR,
        executor=instance(Executor, "an Executor (sim.Executor)"),
        rate=positive,
        max_sim_time=positive,
        run_info=optional(instance(dict, "a dict")),
        observe=optional(CALLABLE),
    )
    def __init__(
        self,
        root: py_trees.behaviour.Behaviour,
        executor: Executor,
        *,
        rate: float = 50.0,
        max_sim_time: float = 120.0,
        run_info: dict | None = None,
        observe: Callable[[Runner, dict], None] | None = None,
    ) -> None:
        cycles = 1.0 / (rate * executor.config.control_period)
        if abs(cycles - round(cycles)) > 1e-9 or round(cycles) < 1:
            raise InputError(
                f"rate {rate} Hz must divide the control rate {1 / executor.config.control_period:g} Hz"
            )
        self.root, self.executor, self.rate, self.max_sim_time = root, executor, rate, max_sim_time
        self.cycles_per_tick = round(cycles)
        self.run_info = dict(run_info or {})
        self.observe = observe
        self.records: list[dict] = []
        self.tick_seconds: list[float] = []  # wall time of each tick of the tree
        self.record_seconds: list[float] = []  # wall time of recording each tick
        self.paths = node_paths(root)
        self.nodes = [(node, self.paths[node.id]) for node in root.iterate()]  # the tree's shape is fixed
        self._object_addresses = object_addresses(executor.world)
        hand = executor.hand
        self._fingers = None if hand is None else hand.fingers.qpos_indices
        self._companions = [  # the other arms driven in lockstep: name, joints, fingers
            (name, arm.arm.qpos_indices, None if arm.hand is None else arm.hand.fingers.qpos_indices)
            for name, arm in executor.companions.items()
        ]

    def run(self, log: str | Path | None = None) -> RunResult:
        """Runs to the end and returns the result (the records are in ``self.records``). With ``log``, the
        JSON-lines log is written as the run goes (:class:`LogStream`): an interrupted run (Ctrl-C) leaves a
        well-formed log up to the interruption, ending with an ``INTERRUPTED`` result, before the
        ``KeyboardInterrupt`` goes on."""
        stream = (
            None if log is None else LogStream(log, {**self.run_info, "nodes": list(self.paths.values())})
        )
        py_trees.blackboard.Blackboard.enable_activity_stream(maximum_size=10000)
        start_sim, start_wall = self.executor.time, time.perf_counter()
        try:
            py_trees.trees.setup(self.root, executor=self.executor)
            status = self._loop(start_sim, stream)
        except KeyboardInterrupt:
            if stream is not None:
                elapsed = (self.executor.time - start_sim, time.perf_counter() - start_wall)
                stream.close(RunResult("INTERRUPTED", *elapsed, len(self.records), None, "interrupted"))
            raise
        except BaseException:
            if stream is not None:
                stream.abandon()
            raise
        finally:
            py_trees.blackboard.Blackboard.disable_activity_stream()
        failed, message = self._outcome(status)
        first = self._first_retried_failure() if status is not Status.SUCCESS else None
        result = RunResult(
            status.value if status in (Status.SUCCESS, Status.FAILURE) else "FAILURE",
            self.executor.time - start_sim,
            time.perf_counter() - start_wall,
            len(self.records),
            failed,
            message,
            None if first == f"{failed}: {message}" else first,
        )
        if stream is not None:
            stream.close(result)
        return result

    def _loop(self, start_sim: float, stream: LogStream | None) -> Status:
        status = Status.RUNNING
        while status is Status.RUNNING:
            begin = time.perf_counter()
            # The root's own tick, not BehaviourTree.tick: that walks the whole tree again after every tick
            # for visitors, and the runner records the nodes itself.
            self.root.tick_once()
            middle = time.perf_counter()
            status = self.root.status
            self.records.append(self._record())
            if stream is not None:
                stream.write(self.records[-1])
            if self.observe is not None:
                self.observe(self, self.records[-1])
            self.tick_seconds.append(middle - begin)
            self.record_seconds.append(time.perf_counter() - middle)
            if status is not Status.RUNNING:
                break
            if self.executor.time - start_sim >= self.max_sim_time:
                self.root.stop(Status.INVALID)
                break
            self.executor.advance(self.cycles_per_tick)
        return status

    def _outcome(self, status: Status) -> tuple[str | None, str]:
        if status is Status.SUCCESS:
            return None, self.root.feedback_message or "succeeded"
        if status is not Status.FAILURE:
            return self.root.name, f"stopped at the sim-time limit of {self.max_sim_time:g} s"
        # The failure's origin: the deepest failed node of the last tick.
        failed = [node for node in self.root.iterate() if node.status is Status.FAILURE]
        tip = max(failed, key=lambda node: self.paths[node.id].count("/"), default=self.root)
        return self.paths[tip.id], tip.feedback_message

    def _first_retried_failure(self) -> str | None:
        """The deepest failed node, "path: message", of the first tick at which a Retry's child failed."""
        retried = [
            self.paths[node.decorated.id]
            for node in self.root.iterate()
            if isinstance(node, py_trees.decorators.Retry)
        ]
        for record in self.records:
            failed = [path for path, status in record["statuses"].items() if status == "FAILURE"]
            for child in retried:
                if child in failed:
                    tip = max((path for path in failed if path.startswith(child)), key=lambda p: p.count("/"))
                    return f"{tip}: {record['feedback'].get(tip, '')}"
        return None

    def _record(self) -> dict:
        statuses, feedback = {}, {}
        for node, path in self.nodes:
            if node.status is not Status.INVALID:
                statuses[path] = _STATUS_NAMES[node.status]
                if node.feedback_message:
                    feedback[path] = node.feedback_message
        stream = py_trees.blackboard.Blackboard.activity_stream
        changes = [
            {
                "key": item.key,
                "activity": item.activity_type,
                "client": item.client_name,
                "value": jsonable(item.current_value),
            }
            for item in stream.data
            if item.activity_type in ("INITIALISED", "WRITE")
        ]
        stream.clear()
        world, gripper = self.executor.world, self.executor.gripper_opening
        qpos = world.data.qpos
        robot = {
            "joints": self.executor.arm.measured().round(5).tolist(),
            "gripper": None if gripper is None else round(gripper, 5),
            "fingers": None if self._fingers is None else qpos[self._fingers].round(5).tolist(),
            "objects": {  # position and orientation (w, x, y, z)
                name: qpos[address : address + 7].round(5).tolist()
                for name, address in self._object_addresses.items()
            },
        }
        if self._companions:
            robot["arms"] = {
                name: {
                    "joints": qpos[joints].round(5).tolist(),
                    "fingers": None if fingers is None else qpos[fingers].round(5).tolist(),
                }
                for name, joints, fingers in self._companions
            }
        return {
            "tick": len(self.records),
            "time": round(self.executor.time, 6),
            "statuses": statuses,
            "feedback": feedback,
            "blackboard": changes,
            "robot": robot,
        }


class LogStream:
    """A run's JSON-lines log, written as the run goes: the header now, one line per tick, the result at the
    end. Lines go to a temporary file beside ``path`` that becomes ``path`` when the result is written, so
    ``path`` is only ever a whole log; it replaces only an earlier run log (anything else there is refused:
    :func:`~besman.core.storage.check_replaceable`); another run writing the same ``path`` at the same
    time is refused (:class:`~besman.core.writer_lock.WriterLock`), and the temporaries of one killed
    meanwhile are removed. A write that fails (a full disk) removes the temporary and the lock and raises a
    :class:`~besman.core.storage.WriteError` naming ``path``."""

    def __init__(self, path: str | Path, run_info: dict) -> None:
        self.path = Path(path)
        check_replaceable(self.path, "--log", LOG_KIND)  # an earlier run log, or nothing
        self._lock = WriterLock(self.path, "--log").acquire()
        # Named for this log, and no live writer of it but this one: a killed run's, nothing else.
        remove_temporaries(self.path.parent, of=self.path.name)
        try:
            descriptor, self._temporary = open_temporary(self.path)
        except OSError as error:
            self._lock.release()
            raise write_error(self.path, error) from error
        self._file = os.fdopen(descriptor, "w", encoding="utf-8")
        self._line({"schema_version": SCHEMA_VERSION, "kind": LOG_KIND, "run": run_info})

    def _line(self, document: dict) -> None:
        try:
            self._file.write(json.dumps(document) + "\n")
        except OSError as error:
            self._fail(error)

    def write(self, record: dict) -> None:
        self._line(record)

    def close(self, result: RunResult) -> Path:
        """Writes the result line and puts the log in place."""
        self._line({"result": asdict(result)})
        try:
            self._file.flush()
            os.fsync(self._file.fileno())
            self._file.close()
            put_in_place(self._temporary, self.path)
        except OSError as error:
            self._fail(error)
        self._release()
        return self.path

    def abandon(self) -> None:
        """Drops the log of a run that broke (the error says why); an older log at ``path`` stays."""
        with contextlib.suppress(OSError):  # the buffer's rest cannot be written on a full disk: dropped
            self._file.close()
        self._temporary.unlink(missing_ok=True)
        self._release()

    def _fail(self, error: OSError) -> NoReturn:
        self.abandon()
        raise write_error(self.path, error) from error

    def _release(self) -> None:
        self._lock.release()  # no lock file left beside the log


@checked(path=PATH, max_bytes=optional(COUNT))
def read_log(path: str | Path, *, max_bytes: int | None = None) -> tuple[dict, list[dict], dict]:
    """(header, tick records, result) of a run log; a ``ValueError`` names the file and line of a problem.
    The log is at most ``max_bytes`` (default: ``$BESMAN_MAX_LOG_BYTES``, else 128 MB: :data:`LOG_LIMIT`)."""
    path = Path(path)
    data = read_bytes(path, LOG_LIMIT.bytes(max_bytes), what="run log", raise_with=LOG_LIMIT.advice)
    records = []
    lines = (line for line in io.BytesIO(data) if line.strip())  # one at a time: no second copy of the log
    for number, line in enumerate(lines, 1):
        records.append(json_value(line, f"{path}:{number}"))
    if not records or records[0].get("kind") != LOG_KIND:
        raise InputError(f"{path}:1: not a besman run log")
    check_schema_version(records[0], SCHEMA_VERSION, f"{path}:1")
    if "result" not in records[-1]:
        raise InputError(f"{path}:{len(records)}: the log ends without a result (the run did not finish)")
    return records[0], records[1:-1], records[-1]["result"]


def statuses(records: list[dict]) -> Iterator[dict[str, str]]:
    """The per-tick node statuses of a run (``Runner.records``) or a log (``read_log(...)[1]``)."""
    return (record["statuses"] for record in records)
