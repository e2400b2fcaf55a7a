"""What the benchmarks of the open-loop tasks (``ball_in_cup.py``, ``puck_strike.py``) share: their command
line, a demonstration replayed or imitated on every held-out tau, the outcome counts of an evaluation and
CMA-ES from the imitated demonstration, one search per seed in lockstep."""

from __future__ import annotations

import argparse
import time

import numpy as np

from besman.learning.search.policy_search import WarmStart, make_optimizer, policy_search
from besman.sim.open_loop import SUCCESS


def arguments(doc: str, *, budget: int, sigma: float, tau: str, tau_help: str) -> argparse.Namespace:
    """The benchmark's command line (``doc``: its module documentation)."""
    parser = argparse.ArgumentParser(description=doc.splitlines()[0])
    parser.add_argument("--json", action="store_true")
    parser.add_argument("--held-out", type=int, default=50)
    parser.add_argument("--seeds", type=int, default=5)
    parser.add_argument("--budget", type=int, default=budget)
    parser.add_argument("--tau", default=tau, help=tau_help)
    parser.add_argument("--sigma", type=float, default=sigma, help="CMA-ES's initial step size (theta units)")
    parser.add_argument("--write-demo", action="store_true", help="rewrite the demonstration file and stop")
    return parser.parse_args()


def outcomes(evaluation, **specific) -> dict:
    """Successes, rollouts, failed references and the mean reward of an evaluation, with the task's own
    ``specific`` counts after the rollouts."""
    details = evaluation.details
    return {
        "success_rate": float(np.mean([d.success for d in details])),
        "successes": int(sum(d.success for d in details)),
        "rollouts": len(details),
        **specific,
        "failed_references": int(sum(d.failure is not None for d in details)),
        "mean_reward": round(float(np.mean(evaluation.rewards)), 4),
    }


def replayed(task, positions, velocities, taus):
    """The evaluation of one joint reference (n_steps + 1, 6), as it is, at every tau (N, d)."""
    n = len(taus)
    return task.evaluate_references(np.repeat(positions[None], n, 0), np.repeat(velocities[None], n, 0), taus)


def everywhere(task, theta, taus):
    """The evaluation of one theta at every tau (N, d)."""
    return task.evaluate(np.repeat(theta[None], len(taus), 0), taus)


def cmaes(
    task,
    theta,
    target,
    taus,
    *,
    sigma: float,
    seeds: int,
    budget: int,
    tau: dict,
    start: dict | None = None,
    with_mean: bool = False,
) -> dict:
    """CMA-ES from ``theta`` at ``target`` (d,), one search per seed in lockstep, until a rollout succeeds
    (every success scores > 0) or ``budget`` rollouts: its report - ``tau`` (the target, named), the start
    reward and ``start`` (more of the start), the rollouts to the first success per seed (the start mean is
    not counted; None: none), ``with_mean`` their mean (None unless every seed succeeded) and their median,
    the seconds it took and each search's best theta's success rate on ``taus``."""
    started = time.perf_counter()
    optimizers = [make_optimizer("cmaes", WarmStart(theta, sigma), seed=seed) for seed in range(seeds)]
    results = policy_search(
        lambda thetas, owners: task.evaluate(thetas, target).rewards,
        optimizers,
        budget=budget,
        target_reward=SUCCESS,
    )
    firsts = []
    for result in results:
        succeeded = np.flatnonzero(np.asarray(result.rewards) > 0)
        firsts.append(int(succeeded[0]) + 1 if succeeded.size else None)
    found = [f for f in firsts if f is not None]
    mean = {"mean_rollouts_to_first_success": float(np.mean(found)) if len(found) == seeds else None}
    return {
        **tau,
        "sigma": sigma,
        "budget": budget,
        "start_reward": results[0].start_reward,
        **(start or {}),
        "rollouts_to_first_success": dict(zip(range(seeds), firsts, strict=True)),
        **(mean if with_mean else {}),
        "median_rollouts_to_first_success": float(np.median(found)) if found else None,
        "seconds": round(time.perf_counter() - started, 1),
        "best_thetas_on_held_out": [
            outcomes(everywhere(task, result.best_theta, taus))["success_rate"] for result in results
        ],
    }
