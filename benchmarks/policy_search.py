"""The optimisers' own cost per generation beside the rollouts they wait for, on the throwing task.

    python benchmarks/policy_search.py [--json] [--generations 20]

For each method (CMA-ES through pycma, xNES), one search on the paper's throwing task (96-D theta, the
default population of 17): the wall time of ``ask`` + ``tell`` per generation and the wall time of
evaluating the generation's throws (``ThrowingRollouts.evaluate``: DMPs, rollouts on all threads, rewards),
measured in the same run. Target: the optimiser's overhead below 10 % of the rollout time.
"""

from __future__ import annotations

import argparse
import json
import statistics
import time

import numpy as np

from besman.learning.search.policy_search import WarmStart, make_optimizer
from besman.tasks.throwing.rollouts import ThrowingRollouts

TARGET_OVERHEAD = 0.10


def measure(method: str, task: ThrowingRollouts, generations: int) -> dict:
    optimizer = make_optimizer(method, WarmStart(task.default_theta(), 0.3), seed=0)
    tau = np.array([-3.5, -3.6])
    optimizer_times, rollout_times = [], []
    for _ in range(generations + 1):
        start = time.perf_counter()
        thetas = optimizer.ask()
        asked = time.perf_counter()
        rewards = task.evaluate(thetas, tau, nan="penalize").rewards
        evaluated = time.perf_counter()
        optimizer.tell(thetas, rewards)
        optimizer_times.append(asked - start + time.perf_counter() - evaluated)
        rollout_times.append(evaluated - asked)
    optimizer_s, rollout_s = statistics.median(optimizer_times[1:]), statistics.median(rollout_times[1:])
    return {
        "population": optimizer.population_size,
        "optimizer_ms_per_generation": 1e3 * optimizer_s,
        "rollouts_ms_per_generation": 1e3 * rollout_s,
        "overhead": optimizer_s / rollout_s,
        "target_overhead": TARGET_OVERHEAD,
    }


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--json", action="store_true")
    parser.add_argument("--generations", type=int, default=20)
    args = parser.parse_args()
    task = ThrowingRollouts()
    report = {method: measure(method, task, args.generations) for method in ("cmaes", "xnes")}
    if args.json:
        print(json.dumps({"benchmark": "policy_search", "dimensions": task.n_params, **report}, indent=2))
        return
    for method, numbers in report.items():
        print(
            f"{method}: {numbers['optimizer_ms_per_generation']:.2f} ms per generation of "
            f"{numbers['population']} beside {numbers['rollouts_ms_per_generation']:.0f} ms of rollouts: "
            f"{100 * numbers['overhead']:.1f} % (target < {100 * TARGET_OVERHEAD:.0f} %)"
        )


if __name__ == "__main__":
    main()
