"""Batched evaluation of candidates, on all local cores or spread over a Ray cluster.

A task evaluates N parameter vectors theta (one per candidate) in task instances tau and returns an
:class:`Evaluation`: one reward per candidate and one detail record per rollout. Every task is a
:class:`BatchedRollouts`: it implements ``evaluate_locally(thetas, taus)`` (its work in this process), is
described by a picklable configuration whose ``build()`` makes the task anywhere, and inherits the one
``evaluate`` that checks a batch and runs it. On top of that:

- ``backend="threads"`` (default) uses every local core. Open-loop tasks run their rollouts in MuJoCo's C
  rollout on its thread pool; closed-loop tasks, whose control runs in Python and would serialise on the
  GIL in threads, run their episodes in a pool of local worker processes (:func:`evaluate_in_processes`).
- ``backend="ray"`` (extra ``distributed``) splits the batch into chunks and evaluates each on a Ray worker,
  which builds the task from its configuration once per worker process (:func:`evaluate_on_ray`).
  Without a running Ray, it starts a local instance that listens on 127.0.0.1 only, or joins the cluster
  that ``RAY_ADDRESS`` names; ``ray.init(address=...)`` before the first batch connects to a cluster too.
  A cluster reachable from the network gets one warning line: Ray runs code for anyone who reaches it
  unless its token authentication is on (CVE-2023-48022).

Rollouts are independent and deterministic, so every backend gives identical results.
"""

from __future__ import annotations

import importlib
import ipaddress
import logging
import math
import multiprocessing
import os
import signal
import subprocess
import threading
import time
from concurrent.futures import ProcessPoolExecutor
from dataclasses import dataclass
from functools import cache
from typing import Any, ClassVar, Protocol

import numpy as np

from besman.core.errors import InputError
from besman.core.moved import old_names
from besman.core.validation import finite_array
from besman.sim import reaper
from besman.skills.task_bounds import TaskBounds

BACKENDS = ("threads", "ray")
PARENT_CHECK_SECONDS = 0.5  # how often a worker process checks that its parent lives
LOOPBACK = "127.0.0.1"
# Ray's switch (read when ``ray`` is imported) that keeps a loopback node address on Linux, where Ray
# otherwise replaces it by the machine's network address and listens on every interface.
RAY_ONE_MACHINE = "RAY_ENABLE_WINDOWS_OR_OSX_CLUSTER"

log = logging.getLogger(__name__)


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


class BatchedRollouts:
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
    """Starts a local Ray instance that listens on 127.0.0.1 only and ends with this process, however it
    ends (:mod:`besman.sim.reaper`), or joins the cluster that ``RAY_ADDRESS`` names (:func:`_init_ray`)."""
    mark = f"{os.getpid()}-{time.time_ns()}"
    _reapers.append(reaper.start(mark))
    os.environ[reaper.OWNER] = mark  # inherited by every process Ray starts
    sigterm = signal.getsignal(signal.SIGTERM)
    terminated = False
    try:
        _init_ray(ray)
    except SystemExit as stop:  # Ray's own SIGTERM handler, in place while Ray starts
        if stop.code != signal.SIGTERM:
            raise
        terminated = True
    if sigterm is not None and threading.current_thread() is threading.main_thread():
        signal.signal(signal.SIGTERM, sigterm)  # besman's (handled as Ctrl-C), not Ray's sys.exit
        if terminated:  # the SIGTERM Ray took, handled now as besman handles it
            os.kill(os.getpid(), signal.SIGTERM)
    if terminated:
        raise KeyboardInterrupt  # where no handler of besman's was there to restore


def _init_ray(ray) -> None:
    """Joins the cluster that ``RAY_ADDRESS`` names, or else starts a Ray instance that only this machine
    can reach: every service of it (GCS, raylet with its object and node managers, workers, dashboard and
    agents) listens on 127.0.0.1, as Ray does when its node address is loopback. On Linux Ray replaces a
    loopback node address unless ``RAY_ONE_MACHINE`` is "0": set for the processes Ray starts and in Ray's
    constants for this one (which may have imported ``ray`` before), both restored once Ray runs. A Ray that
    came up listening elsewhere all the same (another Ray version) is shut down: an error, not a risk."""
    if os.environ.get("RAY_ADDRESS", "local") != "local":
        ray.init(log_to_driver=False)
        return
    constants = importlib.import_module("ray._private.ray_constants")
    saved = os.environ.get(RAY_ONE_MACHINE), constants.ENABLE_RAY_CLUSTER
    os.environ[RAY_ONE_MACHINE], constants.ENABLE_RAY_CLUSTER = "0", False
    # This process's signals are besman's: Ray's C++ failure handler would take a SIGTERM that arrives while
    # Ray starts (a stack dump, then an abort at exit) instead of besman's clean stop.
    constants.RAY_DISABLE_FAILURE_SIGNAL_HANDLER = True
    try:
        ray.init(
            address="local",
            _node_ip_address=LOOPBACK,
            include_dashboard=False,
            dashboard_host=LOOPBACK,
            log_to_driver=False,
        )
    finally:
        constants.ENABLE_RAY_CLUSTER = saved[1]
        if saved[0] is None:
            os.environ.pop(RAY_ONE_MACHINE, None)
        else:
            os.environ[RAY_ONE_MACHINE] = saved[0]
    reachable = [host for host in _ray_hosts(ray) if not _is_loopback(host)]
    if reachable:
        ray.shutdown()
        raise RuntimeError(
            f"Ray {ray.__version__} started on {reachable[0]}, not on {LOOPBACK} only: stopped it"
        )


def _ray_hosts(ray) -> list[str]:
    """The hosts of the Ray this process runs on: its control service's (GCS) and this node's."""
    try:
        gcs = ray.get_runtime_context().gcs_address
        return [gcs.rsplit(":", 1)[0].strip("[]"), ray.util.get_node_ip_address()]
    except Exception:  # a Ray client connection (ray://) tells neither
        return []


def _is_loopback(host: str) -> bool:
    try:
        address = ipaddress.ip_address(host)
    except ValueError:
        return host == "localhost"
    mapped = getattr(address, "ipv4_mapped", None)
    return address.is_loopback or (mapped is not None and mapped.is_loopback)


_warned: set[str] = set()  # the reachable Ray hosts warned about


def _warn_if_reachable(ray) -> None:
    """One warning line for a Ray this process runs on whose control service or node listens beyond this
    machine (a cluster the user connected to, or a Ray started before besman by ``ray.init()``)."""
    reachable = [host for host in _ray_hosts(ray) if not _is_loopback(host)]
    if reachable and reachable[0] not in _warned:
        _warned.add(reachable[0])
        log.warning(
            "besman: warning: Ray at %s is reachable from the network; a Ray cluster runs code for anyone "
            "who reaches it unless its token authentication is on (CVE-2023-48022): keep it on a trusted "
            "network",
            reachable[0],
        )


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
    _warn_if_reachable(ray)
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


__getattr__ = old_names(__name__)  # the old names, for one release (besman.core.moved)
