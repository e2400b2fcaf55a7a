"""Runs on a robot's tabletop (AILA's by default): the box on the table, the place target on the blackboard,
a tree, a log.

The task-specific half of running a tree (the generic runner is :mod:`besman.trees.runner`): the object
and place positions come from the command line (``--set object=x,y``, ``--set place=x,y``, checked against
the robot's pick-and-place bounds) or are drawn from those bounds with a seed; the box is put on the table,
``/task/<name>`` holds every value, and the log header records all of it (the robot too), so :func:`replay`
can run a logged run again and compare its statuses.
"""

from __future__ import annotations

import json
import os
from collections.abc import Iterable, Mapping
from pathlib import Path

import numpy as np
import py_trees

from besman.robots.robot import ROBOT
from besman.sim.executor import Executor
from besman.sim.pick_place import PLACE_TOLERANCE, pick_place_bounds
from besman.sim.world import tabletop_world
from besman.skills.errors import InputError
from besman.skills.validation import PATH, SEED, checked, instance, optional, positive
from besman.trees.blackboard import set_task_values, task_keys_read
from besman.trees.files import describe, load_tree, loads_tree
from besman.trees.runner import Runner, RunResult, read_log, statuses
from besman.trees.summary import Measured, RunSummary

TreeSource = str | Path | py_trees.behaviour.Behaviour
# A tabletop run's arguments, checked where tabletop_run or run_on_tabletop is called.
RUN_ARGUMENTS = {
    "tree": instance(str | os.PathLike | py_trees.behaviour.Behaviour, "a tree file or a root behaviour"),
    "values": optional(instance(Mapping, "a mapping of task values")),
    "seed": optional(SEED),
    "max_sim_time": positive,
    "robot": ROBOT,
}


def pick_place_settings(
    values: dict[str, tuple[float, ...]], seed: int | None, robot: str = "aila"
) -> dict[str, list[float]]:
    """The object and place positions of a tabletop run: given values (checked against the robot's
    pick-and-place bounds) or, where missing, drawn uniformly from those bounds with ``seed``."""
    bounds = pick_place_bounds(robot)
    draw = np.random.default_rng(seed).uniform(bounds.low, bounds.high)
    settings = {name: [float(v) for v in value] for name, value in values.items()}
    for name, columns in (("object", slice(0, 2)), ("place", slice(2, 4))):
        if name in settings:
            if len(settings[name]) != 2:
                raise InputError(f"--set {name}=x,y needs two numbers, got {settings[name]}")
            tau = draw.copy()
            tau[columns] = settings[name]
            bounds.check(tau)  # a value outside the box is rejected with its name
        else:
            settings[name] = draw[columns].tolist()
    return settings


@checked(**RUN_ARGUMENTS)
def tabletop_run(
    tree: TreeSource,
    values: dict[str, tuple[float, ...]] | None = None,
    *,
    seed: int | None = None,
    max_sim_time: float = 120.0,
    robot: str = "aila",
) -> tuple[Runner, dict[str, list[float]]]:
    """A runner for a tree (a file, checked first, or a root behaviour) on ``robot``'s tabletop, ready to
    run: the box stands at ``object`` and ``/task/<name>`` holds every value (``place`` is where the box
    should go)."""
    from_file = not isinstance(tree, py_trees.behaviour.Behaviour)
    root = load_tree(tree) if from_file else tree  # every file problem is reported before anything runs
    known = {"object", "place"} | task_keys_read(root)  # the box's position, the target, what the tree reads
    unknown = sorted(set(values or {}) - known)
    if unknown:
        raise InputError(f"--set {unknown[0]}: not a value of this run; valid: {', '.join(sorted(known))}")
    settings = pick_place_settings(dict(values or {}), seed, robot)
    py_trees.blackboard.Blackboard.clear()
    world = tabletop_world(robot=robot)
    world.place_on("box", "table", *settings["object"])
    set_task_values(settings)
    run_info = {
        "tree": str(Path(tree).resolve()) if from_file else describe(root),
        "robot": robot,
        "settings": settings,
        "seed": seed,
        "max_sim_time": max_sim_time,
    }
    return Runner(root, Executor(world), max_sim_time=max_sim_time, run_info=run_info), settings


@checked(**RUN_ARGUMENTS, log=optional(PATH))
def run_on_tabletop(
    tree: TreeSource,
    values: dict[str, tuple[float, ...]] | None = None,
    *,
    seed: int | None = None,
    log: str | Path | None = None,
    max_sim_time: float = 120.0,
    robot: str = "aila",
) -> RunSummary:
    """Runs a tree on ``robot``'s tabletop (:func:`tabletop_run`) and returns its :func:`summary`."""
    runner, _ = tabletop_run(tree, values, seed=seed, max_sim_time=max_sim_time, robot=robot)
    return summary(runner, runner.run(log=log))


MEASUREMENTS = {
    "placement_error_m": "the box's distance from its place on the shelf, in the plane (None for a tree "
    "that does not read the place target)",
    "box_position": "where the box ended, x, y, z in the world",
}


def measure(runner: Runner) -> Measured:
    """What a tabletop run left (:data:`MEASUREMENTS`): done when the box stands within
    :data:`~besman.sim.pick_place.PLACE_TOLERANCE` of its place, for a tree that reads the place target (one
    that does not places nothing and is judged by its status alone)."""
    box = runner.executor.world.object_pose("box").position
    error = None
    if "place" in task_keys_read(runner.root):
        error = float(np.linalg.norm(box[:2] - np.asarray(runner.run_info["settings"]["place"])))
    outcome = (
        f"placement error {error * 100:.1f} cm"
        if error is not None
        else "box at ({:.3f}, {:.3f}, {:.3f}) m".format(*box)
    )
    return Measured(
        error is None or error <= PLACE_TOLERANCE,
        outcome,
        {"placement_error_m": error, "box_position": [round(float(v), 4) for v in box]},
    )


def summary(runner: Runner, result: RunResult) -> RunSummary:
    """A tabletop run's summary: its :func:`measure` beside how the run ended."""
    return RunSummary.of(runner, result, measure(runner))


def replay(path: str | Path, *, allow_modules: Iterable[str] = ()) -> list[dict[str, str]]:
    """Runs a logged run again from its header; returns its per-tick statuses (to compare with the log's).
    ``allow_modules`` as for :func:`~besman.trees.files.load_tree`."""
    header, _, _ = read_log(path)
    run = header["run"]
    settings = {name: tuple(value) for name, value in run["settings"].items()}
    tree = run["tree"]
    if isinstance(tree, dict):  # a tree built in code, logged in the file format
        tree = loads_tree(json.dumps({"besman_tree": 1, "root": tree}), allow_modules=allow_modules)
    runner, _ = tabletop_run(
        tree, settings, seed=run.get("seed"), max_sim_time=run["max_sim_time"], robot=run.get("robot", "aila")
    )
    runner.run()
    return list(statuses(runner.records))
