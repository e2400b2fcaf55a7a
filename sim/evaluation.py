"""Batched evaluation of candidates, locally on threads or spread over a Ray cluster.

A task evaluates N parameter vectors theta (one per candidate) in task instances tau and returns an
:class:`Evaluation`: one reward per candidate and one detail record per rollout. The ``threads`` backend
runs rollouts on MuJoCo's own thread pool in this process. The ``ray`` backend (extra ``distributed``)
splits the batch into chunks, rebuilds the task from its configuration on each Ray worker (once per worker
process) and evaluates every chunk there with the threads backend; rollouts are independent and
deterministic, so both backends give identical results. Connect to a cluster with
``ray.init(address=...)`` first; without it a local Ray instance is started.
"""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import dataclass
from typing import Any, Protocol

import numpy as np

BACKENDS = ("threads", "ray")


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
    """A picklable description of a task that can rebuild it anywhere."""

    def build(self) -> Any: ...


def check_backend(backend: str) -> None:
    if backend not in BACKENDS:
        raise ValueError(f"backend must be one of {BACKENDS}, got {backend!r}")


_TASKS: dict[Any, Any] = {}  # per worker process: configuration -> built task


def _evaluate_chunk(config: TaskConfig, thetas: np.ndarray, taus: np.ndarray) -> Evaluation:
    if config not in _TASKS:
        _TASKS[config] = config.build()
    return _TASKS[config].evaluate(thetas, taus, backend="threads")


def evaluate_on_ray(
    config: TaskConfig, thetas: np.ndarray, taus: np.ndarray, chunk_size: int | None = None
) -> Evaluation:
    """Evaluates (thetas, taus) in chunks on Ray workers; results come back in order."""
    try:
        import ray
    except ImportError:
        raise ValueError("backend='ray' needs Ray: pip install 'besman[distributed]'") from None
    if not ray.is_initialized():
        ray.init(include_dashboard=False, log_to_driver=False)
    if chunk_size is None:
        workers = max(1, int(ray.available_resources().get("CPU", 1)))
        chunk_size = max(1, math.ceil(len(thetas) / workers))
    remote: Callable = ray.remote(num_cpus=1)(_evaluate_chunk)
    config_reference = ray.put(config)
    futures = [
        remote.remote(config_reference, thetas[start : start + chunk_size], taus[start : start + chunk_size])
        for start in range(0, len(thetas), chunk_size)
    ]
    return Evaluation.concatenate(ray.get(futures))
