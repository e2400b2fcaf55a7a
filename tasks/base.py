"""What every task is: its named task values, the robots it fits, its world, its default tree and its one
success rule.

A :class:`Task` is written once per task (one module of :mod:`besman.tasks`) and is independent of the
robot it runs on; what differs per robot (where the table's objects and targets may be) lives in the task's
module too, keyed by robot name, and a robot the task does not know brings its numbers in its description
(``"tasks": {"<task>": {...}}``, :meth:`Task.robot_numbers`).

tau, the task parameters that skill templates generalise over, is the concatenation of the task's
:class:`TaskValue` s: named groups of numbers (``object``: x, y in m) that ``--set NAME=...`` sets and that
the tree finds on the blackboard as ``/task/NAME``. A run draws the values it is not given uniformly from
the robot's bounds with its seed; without a seed it uses the task's default configuration.

A task sets a run up in :meth:`Task.scene` (the world with its objects placed, the executor, the blackboard
values, what happens that the robot does not plan) and judges it with :meth:`Task.judge`: the one rule that
the demos, ``besman run``, learning rewards and the benchmarks all use.
"""

from __future__ import annotations

from collections.abc import Callable, Iterator, Mapping
from dataclasses import dataclass
from pathlib import Path
from typing import TYPE_CHECKING, Any, ClassVar

import numpy as np

from besman import examples
from besman.core.errors import InputError, UnknownNameError
from besman.core.validation import shown
from besman.skills.task_bounds import TaskBounds

if TYPE_CHECKING:
    from besman.sim.perturbations import Perturbations

Observer = Callable[[Any, dict], None]  # (runner, tick record) -> None, after every tick


@dataclass(frozen=True)
class TaskValue:
    """A named part of tau: ``names`` of its numbers (tau's columns), their ``unit`` (one for all, or one
    each) and what it is. ``whole``: its numbers are whole (an index; drawn as whole numbers, given as
    such); ``choices``: a whole value's meanings, by index (given by name or index: ``--set shape=cylinder``).
    ``surface``: it begins with an x, y point on the world's surface of that name (the viewer's session
    drags it there); ``target``: it is where the task wants something (the viewer marks it)."""

    name: str
    names: tuple[str, ...]
    unit: str | tuple[str, ...]
    meaning: str
    whole: bool = False
    choices: tuple[str, ...] = ()
    surface: str | None = None
    target: bool = False

    @property
    def units(self) -> tuple[str, ...]:
        """The unit of each number."""
        return (self.unit,) * len(self.names) if isinstance(self.unit, str) else self.unit

    def numbers(self, given) -> np.ndarray:
        """``given`` (numbers, or a choice's name) as this value's numbers; an error names the value and
        what it takes."""
        if isinstance(given, str) or (np.ndim(given) == 1 and any(isinstance(v, str) for v in given)):
            words = [given] if isinstance(given, str) else list(given)
            if not self.choices:
                raise InputError(f"--set {self.name}: takes numbers ({', '.join(self.names)}), got {given!r}")
            unknown = [word for word in words if str(word) not in self.choices]
            if unknown:
                raise InputError(f"--set {self.name}: {unknown[0]!r} is not one of {', '.join(self.choices)}")
            return np.array([self.choices.index(str(word)) for word in words], dtype=float)
        try:
            return np.asarray(given, dtype=float).ravel()
        except (TypeError, ValueError):  # a mapping, or lists of unequal lengths
            raise InputError(
                f"--set {self.name}: takes numbers ({', '.join(self.names)}), got {shown(given)}"
            ) from None


@dataclass
class Scene:
    """A task set up for one run: the executor (its world with the robot and the objects placed), the
    ``/task/`` values of the blackboard, the configuration to log (``settings``), an observer of every tick
    for what happens that the robot does not plan (a disturbance, a contact count), and ``judge``: the
    task's success rule applied to this scene once the run has ended."""

    executor: Any
    values: dict
    settings: dict
    judge: Callable[[], Any]  # -> besman.trees.summary.Measured
    observe: Observer | None = None


@dataclass(frozen=True)
class Finding:
    """One robot check of one arm (``besman robots check``, :mod:`besman.tasks.robot_check`): whether it
    passed, what it measured, and what to change if it did not."""

    arm: str
    check: str
    passed: bool
    measured: str
    fix: str = ""


class Task:
    """A task of the registry; a subclass per task sets the class attributes and the methods below."""

    name: ClassVar[str]
    title: ClassVar[str]  # one line: what the task is
    randomised: ClassVar[str]  # what a seed draws
    success: ClassVar[str]  # what counts as success (the rule of judge, in words)
    robot: ClassVar[str]  # the robot it runs on by default
    tree: ClassVar[str | None] = None  # its default tree file, in ``trees`` (None: no demo)
    trees: ClassVar[Path] = examples.path("trees")  # the folder of its tree: besman's examples by default
    aliases: ClassVar[tuple[str, ...]] = ()  # other names it answers to (the demos' earlier names)
    # What it reads from a robot's description under ``"tasks": {"<name>": {...}}`` (:meth:`robot_numbers`),
    # in a few words; "" for nothing (``besman robots check`` reports a section no task reads).
    section: ClassVar[str] = ""
    # The controls its Gymnasium environment takes (:mod:`besman.tasks.environment`), the default first.
    controls: ClassVar[tuple[str, ...]] = ("joint", "ee")
    values: ClassVar[tuple[TaskValue, ...]] = ()
    measurements: ClassVar[Mapping[str, str]] = {}  # what judge measures: name -> meaning
    max_sim_time: ClassVar[float] = 120.0  # s of simulated time a run may take
    # What a perturbed run varies (besman.sim.perturbations), acting on the object of that name; None: the
    # task is not perturbed.
    perturbations: ClassVar[Perturbations | None] = None
    perturbed_object: ClassVar[str] = "box"

    # -- what a subclass defines ---------------------------------------------------------------------------

    def fits(self, robot) -> bool:
        """Whether the task runs on ``robot`` (a :class:`~besman.robots.RobotDescription`)."""
        raise NotImplementedError

    def bounds(self, robot: str) -> TaskBounds:
        """tau's box on ``robot``."""
        raise NotImplementedError

    def scene(self, robot: str, values: dict[str, np.ndarray], seed: int | None) -> Scene:
        """The task set up on ``robot`` for the task values ``values`` (all of them, checked), ``seed``
        drawing whatever else the task randomises."""
        raise NotImplementedError

    def default_values(self, robot: str) -> dict[str, np.ndarray]:
        """The values of a run without a seed: the middle of tau's box (whole values rounded down)."""
        bounds = self.bounds(robot)
        middle = (np.asarray(bounds.low) + np.asarray(bounds.high)) / 2
        whole = self._whole_columns()
        middle[whole] = np.floor(middle[whole])
        return self.split(middle)

    def batched(self, robot: str):
        """The task as a :class:`~besman.sim.evaluation.BatchedRollouts` (thetas of a scripted plan, taus) for
        policy search, or None if the task has no scripted plan."""
        return None

    def building_blocks(self, robot: str):
        """The blocks that learning imitates and refines for this task on ``robot``
        (:class:`~besman.learning.pipeline.building_blocks.BuildingBlocks`), or None if the task learns
        none."""
        return None

    def facts(self, robot: str) -> dict:
        """More JSON-ready facts of the task on ``robot`` for ``besman tasks show`` (e.g. its areas)."""
        return {}

    def robot_checks(self, robot: str, description) -> Iterator[Finding]:
        """The task's own checks of ``robot`` (``description``: its
        :class:`~besman.robots.RobotDescription`) for ``besman robots check``, one
        :class:`Finding` at a time (the checks' helpers are there too); none by
        default. They run after the arm and gripper checks, on a robot with a tabletop, for every task of
        the registry once, whether it fits the robot or not: checks of what the task needs yield nothing
        where :meth:`fits` is false, a check of why it does not fit says so (pick-place's place area). A
        subclass inherits its parent's checks: one that is not their owner yields nothing."""
        return iter(())

    # -- shared --------------------------------------------------------------------------------------------

    @property
    def tree_path(self) -> Path | None:
        return None if self.tree is None else Path(self.trees) / self.tree

    @property
    def names(self) -> tuple[str, ...]:
        """tau's names, in order."""
        return tuple(name for value in self.values for name in value.names)

    def check_robot(self, robot: str | None) -> str:
        """``robot`` (default: the task's own) if the task fits it; otherwise an error naming the robots
        that fit, before any work."""
        import besman.robots as robots

        return robots.choose(robot, self.robot, self.fits, f"task {self.name}")

    def robot_numbers(self, robot: str, known: Mapping[str, Any], parse: Callable[[dict, str, Any], Any]):
        """The task's numbers for ``robot``: ``known`` ones (by the robot's name) or those its description
        brings under ``"tasks": {"<task>": {...}}`` (read by ``parse(section, where, tabletop)``, whose errors
        name the file and field; ``tabletop`` is the robot's work surface, or None); None if neither has
        them."""
        import besman.robots as robots

        description = robots.describe(robot)
        section = description.tasks.get(self.name)
        if section is not None:
            return parse(section, f"{description.file}: tasks.{self.name}", description.tabletop)
        return known.get(description.name)

    def split(self, tau) -> dict[str, np.ndarray]:
        """tau as its named values."""
        tau, start, values = np.asarray(tau, dtype=float), 0, {}
        for value in self.values:
            values[value.name] = tau[start : start + len(value.names)]
            start += len(value.names)
        return values

    def join(self, values: Mapping[str, Any]) -> np.ndarray:
        """The named values as tau."""
        return np.concatenate(
            [np.empty(0), *(np.asarray(values[value.name], dtype=float) for value in self.values)]
        )

    def resolve(self, robot: str, given: Mapping[str, Any], seed: int | None) -> dict[str, np.ndarray]:
        """Every task value of a run: the ``given`` ones (checked: known names, right counts, inside the
        robot's box), the others drawn from the box with ``seed`` or, without one, the task's defaults."""
        by_name = {value.name: value for value in self.values}
        unknown = sorted(set(given) - set(by_name))
        if unknown:
            raise UnknownNameError(
                f"--set {unknown[0]}: not a value of task {self.name}; its values: "
                + (", ".join(by_name) or "none")
            )
        bounds = self.bounds(robot)
        if seed is None:
            values = self.default_values(robot)
        else:
            values = self.split(self.draw(robot, np.random.default_rng(seed)))
        for name, numbers in given.items():
            value = by_name[name]
            numbers = value.numbers(numbers)
            if len(numbers) != len(value.names):
                raise InputError(
                    f"--set {name} needs {len(value.names)} number(s) ({', '.join(value.names)}), got "
                    f"{len(numbers)}"
                )
            if value.whole and not np.array_equal(numbers, np.round(numbers)):
                raise InputError(f"--set {name}: {', '.join(value.names)} must be whole numbers")
            values[name] = numbers
        bounds.check(self.join(values))  # a value outside the box is refused with its name and the box
        return values

    def draw(self, robot: str, rng: np.random.Generator) -> np.ndarray:
        """A tau drawn uniformly from the robot's box (whole values: each whole number equally likely)."""
        bounds = self.bounds(robot)
        low, high = np.asarray(bounds.low), np.asarray(bounds.high)
        tau = rng.uniform(low, high)
        whole = self._whole_columns()
        tau[whole] = rng.integers(low[whole], high[whole] + 1)
        return tau

    def spread(self, robot: str, count: int, seed: int) -> np.ndarray:
        """``count`` taus spread over the robot's box (a Latin hypercube: each column's range cut in
        ``count`` strata, one tau in each; whole values take the strata's whole numbers in turn)."""
        from scipy.stats import qmc

        bounds = self.bounds(robot)
        low, high = np.asarray(bounds.low), np.asarray(bounds.high)
        unit = qmc.LatinHypercube(d=len(low), seed=seed).random(count)
        taus = low + unit * (high - low)
        whole = self._whole_columns()
        taus[:, whole] = np.minimum(
            low[whole] + np.floor(unit[:, whole] * (high - low + 1)[whole]), high[whole]
        )
        return taus

    def _columns(self, robot: str) -> list[dict]:
        """tau's columns on ``robot``: each one's name, value, unit and range (and a choice's names)."""
        bounds, columns = self.bounds(robot), []
        for value in self.values:
            for name, unit in zip(value.names, value.units, strict=True):
                index = bounds.names.index(name)
                column = {"name": name, "value": value.name, "unit": unit}
                column["range"] = [bounds.low[index], bounds.high[index]]
                if value.choices:
                    column["choices"] = list(value.choices)
                columns.append(column)
        return columns

    def _whole_columns(self) -> np.ndarray:
        return np.array([value.whole for value in self.values for _ in value.names], dtype=bool)

    def describe(self, robot: str | None = None) -> dict:
        """The task on ``robot`` as JSON-ready facts: name, robot, what it is, what is randomised, success,
        tau's box, its default tree and the task's own facts."""
        robot = self.check_robot(robot)
        import besman.robots as robots

        return {
            "task": self.name,
            "robot": robots.describe(robot).name,
            "title": self.title,
            "randomised": self.randomised,
            "success": self.success,
            "tree": self.tree,
            "values": {
                value.name: {
                    "names": list(value.names),
                    "units": list(value.units),
                    "meaning": value.meaning,
                    **({"choices": list(value.choices)} if value.choices else {}),
                }
                for value in self.values
            },
            "tau": self._columns(robot),
            **self.facts(robot),
        }
