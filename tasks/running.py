"""Running a tree on a task: every ``besman run``, every demo and every replay goes through here.

:func:`prepare` checks the tree (a file, or a root built in code) and the task values before any work, sets
the task's scene up on the robot (:meth:`~besman.tasks.base.Task.scene`), writes ``/task/<name>`` and
returns a :class:`TaskRun`: the runner, ready to run, and how the task judges the run. The runner's log
header names the task, the tree, the robot, the seed and the values given, which is all :func:`replay` (and
the viewer's replay, :func:`executor_of`) needs to rebuild the run. A demo is a task run with its default
tree (:func:`run_demo`).
"""

from __future__ import annotations

import json
import os
from collections.abc import Callable, Iterable, Mapping
from dataclasses import dataclass
from pathlib import Path

import numpy as np
import py_trees

from besman.core.errors import InputError
from besman.core.seeds import child_seed
from besman.core.validation import CALLABLE, PATH, SEED, checked, instance, optional, positive, text
from besman.robots.catalogue import ROBOT
from besman.sim.perturbations import check_mode
from besman.tasks import task as find_task
from besman.tasks.base import Observer, Task
from besman.trees.blackboard import set_task_values, task_keys_read
from besman.trees.files import describe, load_tree, loads_tree, tree_task
from besman.trees.runner import Runner, RunResult, read_log, statuses
from besman.trees.summary import RunSummary

TreeSource = str | os.PathLike | py_trees.behaviour.Behaviour


@dataclass(frozen=True)
class TaskRun:
    """A prepared run: the runner (not started; its configuration is in ``runner.run_info``) and the task's
    judgement of the scene once the run has ended."""

    runner: Runner
    measure: Callable

    def judge(self, result: RunResult) -> RunSummary:
        """The summary of the run that ended with ``result``."""
        return RunSummary.of(self.runner, result, self.measure())


def observers(*calls: Observer | None) -> Observer | None:
    """One runner observer that calls the given ones in turn (None if none is given)."""
    calls = [call for call in calls if call is not None]
    if len(calls) <= 1:
        return calls[0] if calls else None

    def observe(runner: Runner, record: dict) -> None:
        for call in calls:
            call(runner, record)

    return observe


RUN_ARGUMENTS = {
    "task": optional(instance(str | Task, "a task name or a Task")),
    "tree": optional(instance(str | os.PathLike | py_trees.behaviour.Behaviour, "a tree file or a root")),
    "robot": optional(ROBOT),
    "seed": optional(SEED),
    "values": optional(instance(Mapping, "a mapping of task values (name -> numbers)")),
    "observe": optional(CALLABLE),
    "max_sim_time": optional(positive),
    "pool": optional(PATH),
    "demo": optional(text("a demo name")),
    "perturb": optional(text("a perturbation mode")),
}


@checked(**RUN_ARGUMENTS, allow_modules=instance(Iterable, "module names"))
def prepare(
    task: str | Task | None = None,
    tree: TreeSource | None = None,
    *,
    robot: str | None = None,
    seed: int | None = None,
    values: Mapping | None = None,
    observe: Observer | None = None,
    max_sim_time: float | None = None,
    pool: str | Path | None = None,
    allow_modules: Iterable[str] = (),
    demo: str | None = None,
    perturb: str | None = None,
) -> TaskRun:
    """A run of ``tree`` (default: the task's own) on ``task`` (default: the one the tree file names) on
    ``robot`` (default: the task's), its task values ``values`` given or drawn with ``seed``; ``pool``
    replaces the pools the tree names; ``perturb`` ("perception" or "push") perturbs the run as the task
    declares (:mod:`besman.sim.perturbations`, drawn with ``seed``). Everything is checked before the scene
    is built: the tree file, the task and robot, and the values (names, counts, inside the robot's box)."""
    if task is None and tree is None:
        raise InputError("a run needs a task or a tree file that names its task")
    from_file = tree is not None and not isinstance(tree, py_trees.behaviour.Behaviour)
    if task is None and not from_file:
        raise InputError("a tree built in code runs on a task: give task= (besman tasks lists them)")
    if pool is not None and not from_file:
        raise InputError("pool replaces the pools a tree file names; a tree built in code has its own")
    if isinstance(task, str):
        task = find_task(task)
    if from_file and task is not None:
        named = tree_task(tree)
        if named is not None and find_task(named) is not task:
            raise InputError(f"{tree}: the tree is for task {named}, not {task.name}")
    if task is None:
        named = tree_task(tree)
        if named is None:
            raise InputError(
                f"{tree}: the tree names no task (a top-level 'task:' field, besman tasks lists them): it is "
                "a subtree for other trees to include"
            )
        task = find_task(named)
    if tree is None:
        if task.tree_path is None:
            raise InputError(f"task {task.name} has no default tree; give a tree file")
        tree, from_file = task.tree_path, True
    robot = task.check_robot(robot)
    _check_perturb(task, perturb, seed)
    if from_file:
        import besman.robots as robots

        name = robots.describe(robot).name
        root = load_tree(tree, pool=pool, allow_modules=allow_modules, robot=name)
    else:
        root = tree
    given = dict(values or {})
    known = {value.name for value in task.values}
    read = task_keys_read(root) - known
    extra = {name: np.asarray(value, dtype=float) for name, value in given.items() if name in read}
    task_values = task.resolve(robot, {k: v for k, v in given.items() if k not in read}, seed)
    py_trees.blackboard.Blackboard.clear()
    scene = task.scene(robot, task_values, seed)
    observe_perturbation, perturbation = _perturbed(task, scene, perturb, seed)
    set_task_values({**scene.values, **_as_held(extra, scene.values)})
    run_info = {
        "task": task.name,
        "demo": demo,
        "tree": str(Path(tree).resolve()) if from_file else describe(root),
        "robot": robot,
        "seed": seed,
        "values": {
            name: np.asarray(value, dtype=float).tolist() for name, value in {**task_values, **extra}.items()
        },
        "pool": None if pool is None else str(Path(pool).resolve()),
        "settings": scene.settings,
        "max_sim_time": max_sim_time or task.max_sim_time,
        "perturb": perturb,
    }
    if perturbation:
        run_info["perturbation"] = perturbation
    runner = Runner(
        root,
        scene.executor,
        max_sim_time=run_info["max_sim_time"],
        run_info=run_info,
        observe=observers(scene.observe, observe_perturbation, observe),
    )
    return TaskRun(runner, scene.judge)


def _as_held(given: Mapping[str, np.ndarray], held: Mapping[str, object]) -> dict:
    """``given`` /task values (numbers) in the form the scene holds them (``held``): a hand pose,
    ``{"position": [x, y, z], "yaw": rad}``, from x, y, z in m and a yaw in degrees (optional)."""
    shaped = {}
    for name, numbers in given.items():
        current = held.get(name)
        if not (isinstance(current, Mapping) and "position" in current):
            shaped[name] = numbers
        elif numbers.shape in ((3,), (4,)) and np.isfinite(numbers).all():
            yaw = float(np.radians(numbers[3])) if numbers.size == 4 else None
            shaped[name] = {"position": numbers[:3].tolist(), "yaw": yaw}
        else:
            raise InputError(
                f"--set {name}: a hand pose, x, y, z in m and a yaw in degrees if it turns the hand; got "
                f"{numbers.tolist()}"
            )
    return shaped


PERTURBATION_STREAM = 7  # the child of the run's seed that draws its perturbations


def _check_perturb(task: Task, perturb: str | None, seed: int | None) -> None:
    check_mode(perturb)
    if perturb is not None and task.perturbations is None:
        raise InputError(f"--perturb: task {task.name} declares no perturbations")
    if perturb is not None and seed is None:
        raise InputError("--perturb: a perturbed run draws its perturbations with its seed: give --seed")


def _perturbed(task: Task, scene, perturb: str | None, seed: int | None) -> tuple[Observer | None, dict]:
    """Sets the run's perturbations up in ``scene`` (its world's perception); the observer that pushes the
    object (or None) and what was drawn, for the log."""
    if perturb is None:
        return None, {}
    model = task.perturbations
    rng = np.random.default_rng(child_seed(seed, PERTURBATION_STREAM))
    scene.executor.world.perception = model.perception(rng)
    described = {"mode": perturb, **model.describe()}
    if perturb != "push":
        return None, described
    push = model.push_of(task.perturbed_object, rng)
    return (lambda runner, _: push(runner.executor)), {**described, "push": push.describe()}


@checked(log=optional(PATH))
def run(
    task: str | Task | None = None,
    tree: TreeSource | None = None,
    *,
    log: str | Path | None = None,
    **options,
) -> RunSummary:
    """Runs a tree on a task and returns its summary; ``options`` as for :func:`prepare`, ``log`` the
    JSON-lines log to write."""
    prepared = prepare(task, tree, **options)
    return prepared.judge(prepared.runner.run(log=log))


@checked(name=text("a task name"), robot=optional(ROBOT), seed=optional(SEED), log=optional(PATH))
def run_demo(
    name: str,
    seed: int | None = None,
    *,
    robot: str | None = None,
    values: Mapping | None = None,
    log: str | Path | None = None,
    observe: Observer | None = None,
) -> RunSummary:
    """Runs the demo of task ``name``: its default tree, on ``robot`` (default: the task's), ``seed``
    drawing the configuration (none: the task's default one)."""
    found = find_task(name)
    return run(found, robot=robot, seed=seed, values=values, observe=observe, log=log, demo=found.name)


def _rebuild(header: dict, allow_modules: Iterable[str]) -> TaskRun:
    """The run a log's header describes, prepared again."""
    run_info = header["run"]
    tree = run_info["tree"]
    if isinstance(tree, dict):  # a tree built in code, logged in the file format
        tree = loads_tree(json.dumps({"besman_tree": 1, "root": tree}), allow_modules=allow_modules)
    return prepare(
        run_info.get("task"),
        tree,
        robot=run_info.get("robot"),
        seed=run_info.get("seed"),
        values=run_info.get("values") or {},
        max_sim_time=run_info.get("max_sim_time"),
        pool=run_info.get("pool"),
        allow_modules=allow_modules,
        demo=run_info.get("demo"),
        perturb=run_info.get("perturb"),
    )


def replay(path: str | Path, *, allow_modules: Iterable[str] = ()) -> list[dict[str, str]]:
    """Runs a logged run again from its header; returns its per-tick statuses (to compare with the log's).
    ``allow_modules`` as for :func:`~besman.trees.files.load_tree`."""
    header, _, _ = read_log(path)
    if "task" not in header.get("run", {}):
        raise InputError(f"{path}: the log names no task (written by an earlier besman); run the tree again")
    runner = _rebuild(header, allow_modules).runner
    runner.run()
    return list(statuses(runner.records))


def executor_of(header: dict):
    """The executor (its world, arms and hands) of a logged run, rebuilt from its header."""
    return _rebuild(header, ()).runner.executor
