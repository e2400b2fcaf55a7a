"""Whole runs of a tree file on its task, batched as rollouts: each rollout is one ``besman run`` (the tree,
the robot, the task's values and the run's seed), so that many runs spread over the local worker processes
or a Ray cluster (:mod:`besman.sim.evaluation`) and give the same outcome, to the last digit, on each.

theta is empty: the tree fixes what is learned (the pools its file names). tau is the task's values
(:meth:`~besman.tasks.base.Task.split` order), then the run's seed, which draws what the task randomises
beyond them (a slip, the object's mass, the perturbations). The reward is 1 for a success, else 0; the
detail is the run's :class:`EpisodeOutcome`.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from besman.sim.evaluation import BatchedRollouts, Evaluation
from besman.sim.faults import counted_warnings
from besman.skills.task_bounds import TaskBounds

SEED_RANGE = 2**31


class MotionTrail:
    """An observer of a run (``observe=`` of :func:`~besman.tasks.running.run`) that keeps every motion the
    executor started, in order, each with the row of the executor's log at which it started: what a run did,
    for counting its attempts and measuring its motions."""

    def __init__(self) -> None:
        self.started: list[tuple] = []  # (motion, its first row in the executor's log)

    def __call__(self, runner, _record) -> None:
        executor = runner.executor
        motion = executor.motion
        if motion is not None and (not self.started or self.started[-1][0] is not motion):
            self.started.append((motion, len(executor.log) - motion.cycles))

    @property
    def motions(self) -> list:
        return [motion for motion, _ in self.started]


@dataclass(frozen=True)
class EpisodeOutcome:
    """What one run ended with: the task's judgement and measurements, the motions in the order they ran
    (``name: status``), the run's length, the world's final state (every joint's position and velocity,
    free bodies included) and the MuJoCo warnings its simulation counted (e.g. ``BADQACC: 1``, "simulation
    is unstable"), which a worker process or a Ray worker would otherwise only print. Wall-clock time is
    left out: it is the one thing that differs between runs."""

    success: bool
    outcome: str
    measurements: dict
    motions: tuple[str, ...]
    sim_time_s: float
    ticks: int
    failed_node: str | None
    message: str
    qpos: tuple[float, ...]
    qvel: tuple[float, ...]
    warnings: tuple[str, ...]


@dataclass(frozen=True)
class TreeEpisodesConfig:
    """The tree file (a path), its task, the robot and the perturbation mode of every run (None, or as
    ``besman run --perturb``)."""

    task: str
    tree: str
    robot: str
    perturb: str | None = None

    def build(self) -> TreeEpisodes:
        return TreeEpisodes(self)


class TreeEpisodes(BatchedRollouts):
    """Runs of one tree on its task; see the module documentation."""

    n_params = 0

    def __init__(self, config: TreeEpisodesConfig) -> None:
        from besman.tasks import task

        self.config = config
        self.task = task(config.task)
        values = self.task.bounds(config.robot)
        self.bounds = TaskBounds((*values.names, "seed"), (*values.low, 0), (*values.high, SEED_RANGE - 1))

    def evaluate_locally(self, thetas: np.ndarray, taus: np.ndarray) -> Evaluation:
        details = tuple(self.episode(tau) for tau in taus)
        return Evaluation(np.array([float(detail.success) for detail in details]), details)

    def episode(self, tau: np.ndarray) -> EpisodeOutcome:
        """One run of the tree at ``tau`` (the task's values, then the seed)."""
        from besman.tasks.running import prepare

        trail = MotionTrail()
        prepared = prepare(
            self.task,
            self.config.tree,
            robot=self.config.robot,
            values=self.task.split(tau[:-1]),
            seed=int(tau[-1]),
            perturb=self.config.perturb,
            observe=trail,
        )
        summary = prepared.judge(prepared.runner.run())
        data = prepared.runner.executor.world.data
        return EpisodeOutcome(
            success=summary.success,
            outcome=summary.outcome,
            measurements=summary.measurements,
            motions=tuple(f"{motion.name}: {motion.status.value}" for motion in trail.motions),
            sim_time_s=summary.sim_time_s,
            ticks=summary.ticks,
            failed_node=summary.failed_node,
            message=summary.message,
            qpos=tuple(data.qpos.tolist()),
            qvel=tuple(data.qvel.tolist()),
            warnings=counted_warnings(data),
        )
