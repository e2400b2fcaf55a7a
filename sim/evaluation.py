"""Batched evaluation of candidates, on all local cores or spread over a Ray cluster.

A task evaluates N parameter vectors theta (one per candidate) in task instances tau and returns an
:class:`Evaluation`: one reward per candidate and one detail record per rollout. Every task is a
:class:`BatchedTask`: it implements ``evaluate_locally(thetas, taus)`` (its work in this process), is
described by a picklable configuration whose ``build()`` makes the task anywhere, and inherits the one
``evaluate`` that checks a batch and runs it. On top of that:

- ``backend="threads"`` (default) uses every local core. Open-loop tasks run their rollouts in MuJoCo's C
  rollout on its thread pool; closed-loop tasks, whose control runs in Python and would serialise on the
  GIL in threads, run their episodes in a pool of local worker processes (:func:`evaluate_in_processes`).
- ``backend="ray"`` (extra ``distributed``) splits the batch into chunks and evaluates each on a Ray worker,
  which builds the task from its configuration once per worker process (:func:`evaluate_on_ray`).
  Connect to a cluster with ``ray.init(address=...)`` first; without it a local Ray instance is started.

Rollouts are independent and deterministic, so every backend gives identical results.
"""

from __future__ import annotations

import math
import multiprocessing
import os
import subprocess
import threading
import time
from concurrent.futures import ProcessPoolExecutor
from dataclasses import dataclass
from functools import cache
from typing import Any, ClassVar, Protocol

import numpy as np

from besman.sim import reaper
from besman.skills.errors import InputError
from besman.skills.tasks import TaskBounds
from besman.skills.validation import finite_array

BACKENDS = ("threads", "ray")
PARENT_CHECK_SECONDS = 0.5  # how often a worker process checks that its parent lives


@dataclass(frozen=True)
class Evaluation:
    """Rewards (N,) and one detail record per rollout (task-specific, e.g. landing point and failure)."""

    rewards: np.ndarray
    details: tuple[Any, ...]

    @staticmethod
    def concatenate(parts: list[Evaluation]) -> Evaluation:
        return Evaluation(
            np.concatenate([part.rewards for part in parts]),
            tuple(detail for part in parts for detail in part.details),
        )


class TaskConfig(Protocol):
    """A picklable (hashable) description of a task that can rebuild it anywhere."""

    def build(self) -> Any: ...


def check_backend(backend: str) -> None:
    if backend not in BACKENDS:
        raise InputError(f"backend must be one of {BACKENDS}, got {backend!r}")


class BatchedTask:
    """What every simulated task shares: :meth:`evaluate` checks a batch before any work (finite thetas of
    ``n_params`` entries each, each one a candidate the task can run by :meth:`check_theta`, taus in the
    task's box) and runs it on the backend.

    A task sets ``config`` (its picklable configuration) and ``bounds`` (tau's box), has ``n_params`` and
    implements ``evaluate_locally``; ``in_processes`` says where its local work runs: in worker processes
    (closed-loop control written in Python) or here (MuJoCo's threaded rollouts).
    """

    config: TaskConfig
    bounds: TaskBounds
    n_params: int
    in_processes: ClassVar[bool] = True

    def check_theta(self, theta: np.ndarray) -> None:
        """Raises an :class:`InputError` for a candidate the task cannot run (default: none)."""

    def checked(self, thetas, taus) -> tuple[np.ndarray, np.ndarray]:
        """Thetas (N, n_params) and taus (N, d) from one or N of each, checked."""
        thetas = finite_array("theta", thetas)
        thetas = thetas[None] if thetas.ndim == 1 else thetas
        if thetas.ndim != 2 or thetas.shape[1] != self.n_params:
            raise InputError(f"theta must have {self.n_params} entries, got shape {thetas.shape[1:]}")
        for theta in thetas:
            self.check_theta(theta)
        return thetas, self.bounds.check(taus, n=len(thetas))

    def evaluate(self, thetas, taus, *, backend: str = "threads") -> Evaluation:
        """Rewards (N,) and one detail per rollout for thetas (N, n_params) or (n_params,) in taus (N, d) or
        (d,); the same inputs give the same results on every backend."""
        check_backend(backend)
        thetas, taus = self.checked(thetas, taus)
        if backend == "ray":
            return evaluate_on_ray(self.config, thetas, taus)
        if self.in_processes:
            return evaluate_in_processes(self.config, thetas, taus)
        return self.evaluate_locally(thetas, taus)

    def evaluate_locally(self, thetas: np.ndarray, taus: np.ndarray) -> Evaluation:
        raise NotImplementedError


_TASKS: dict[Any, Any] = {}  # per worker process: configuration -> built task


def _evaluate_chunk(config: TaskConfig, thetas: np.ndarray, taus: np.ndarray) -> Evaluation:
    if config not in _TASKS:
        _TASKS[config] = config.build()
    return _TASKS[config].evaluate_locally(thetas, taus)


def _chunks(count: int, workers: int) -> list[slice]:
    size = max(1, math.ceil(count / workers))
    return [slice(start, start + size) for start in range(0, count, size)]


@cache
def _process_pool(workers: int) -> ProcessPoolExecutor:
    # "spawn": a fresh interpreter per worker, safe with MuJoCo's and BLAS's threads (fork is not).
    return ProcessPoolExecutor(
        workers,
        mp_context=multiprocessing.get_context("spawn"),
        initializer=_end_with_parent,
        initargs=(os.getpid(),),
    )


def _end_with_parent(parent: int) -> None:
    """Ends this worker process within a second of its parent's death, however the parent dies: a worker in
    the middle of a chunk would otherwise run it to the end (minutes) after a ``kill -9``, burning the cores
    a resumed run needs. A watcher thread, not the parent-death signal: that signal fires when the thread
    that started the worker ends, not the process."""

    def watch() -> None:
        while os.getppid() == parent:
            time.sleep(PARENT_CHECK_SECONDS)
        os._exit(1)

    threading.Thread(target=watch, name="end-with-parent", daemon=True).start()


def evaluate_in_processes(config: TaskConfig, thetas: np.ndarray, taus: np.ndarray) -> Evaluation:
    """Evaluates (thetas, taus) in chunks on a persistent pool of local worker processes (one per core);
    each worker builds the task once. Results come back in order."""
    workers = min(len(thetas), os.cpu_count() or 1)
    if workers <= 1:
        return _evaluate_chunk(config, thetas, taus)
    pool = _process_pool(os.cpu_count() or 1)
    parts = [
        pool.submit(_evaluate_chunk, config, thetas[part], taus[part])
        for part in _chunks(len(thetas), workers)
    ]
    return Evaluation.concatenate([part.result() for part in parts])


_reapers: list[subprocess.Popen] = []  # the reaper of the Ray this process started (its pipe stays open)


def _start_local_ray(ray) -> None:
    """Starts a local Ray instance that ends with this process, however it ends (:mod:`besman.sim.reaper`)."""
    mark = f"{os.getpid()}-{time.time_ns()}"
    _reapers.append(reaper.start(mark))
    os.environ[reaper.OWNER] = mark  # inherited by every process Ray starts
    ray.init(include_dashboard=False, log_to_driver=False)


def evaluate_on_ray(
    config: TaskConfig, thetas: np.ndarray, taus: np.ndarray, chunk_size: int | None = None
) -> Evaluation:
    """Evaluates (thetas, taus) in chunks on Ray workers; results come back in order."""
    try:
        import ray
    except ImportError:
        raise InputError("backend='ray' needs Ray: pip install 'besman[distributed]'") from None
    if not ray.is_initialized():
        _start_local_ray(ray)
    workers = max(1, int(ray.available_resources().get("CPU", 1)))
    parts = (
        _chunks(len(thetas), workers)
        if chunk_size is None
        else [slice(start, start + chunk_size) for start in range(0, len(thetas), chunk_size)]
    )
    remote = ray.remote(num_cpus=1)(_evaluate_chunk)
    config_reference = ray.put(config)
    futures = [remote.remote(config_reference, thetas[part], taus[part]) for part in parts]
    return Evaluation.concatenate(ray.get(futures))
