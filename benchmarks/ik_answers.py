"""Planning with the arms' inverse-kinematics answers kept against solving every question again: processor
time side by side, and the same outcomes to the last digit.

    python benchmarks/ik_answers.py [--json] [--task stack] [--episodes 3]

Whole runs of the task's learned tree on AILA at task values drawn with seed 541 (the reproduction test's),
each configuration run with the answers kept (``besman.sim.arm.IK_ANSWERS_KEPT``) and with none kept, in
alternation, in this process after a first run that loads everything. Reported: the processor time of each
(``time.process_time``: the machine's other load counts less than in wall time), their ratio, the solves
and distinct questions of the kept runs, and whether every outcome (each run's reward and every measure of
its detail, as ``repr``) is the same both ways - the claim is that keeping answers changes nothing but the
time.
"""

from __future__ import annotations

import argparse
import json
import time
from pathlib import Path

import numpy as np

import besman.robots as robots
import besman.sim.arm as arm_module
from besman.tasks import task
from besman.tasks.episodes import TreeEpisodesConfig

ROOT = Path(__file__).resolve().parents[1]
SEED = 541


def run(rollouts, taus: np.ndarray, kept: int) -> tuple[float, int, list[str]]:
    """Processor seconds, inverse-kinematics solves and outcomes of the runs at ``taus`` with ``kept``
    answers kept per arm."""
    arm_module.IK_ANSWERS_KEPT, solves, solve = kept, [0], robots.solve_ik

    def counted(*args, **kwargs):
        solves[0] += 1
        return solve(*args, **kwargs)

    robots.solve_ik = counted
    try:
        started = time.process_time()
        evaluation = rollouts.evaluate_locally(np.empty((len(taus), 0)), taus)
        seconds = time.process_time() - started
    finally:
        robots.solve_ik = solve
    outcomes = [repr(r) + repr(d) for r, d in zip(evaluation.rewards, evaluation.details, strict=True)]
    return seconds, solves[0], outcomes


def measure(name: str, episodes: int) -> dict:
    entry, rng = task(name), np.random.default_rng(SEED)
    tree = ROOT / "examples" / "trees" / f"{name}_learned.yaml"
    rollouts = TreeEpisodesConfig(name, str(tree), "aila").build()
    taus = np.array([[*entry.draw("aila", rng), rng.integers(0, 2**31)] for _ in range(episodes + 1)])
    default = arm_module.IK_ANSWERS_KEPT
    try:
        run(rollouts, taus[:1], default)  # imports, compiled models: not what is compared
        times, solves, same = {"kept": [], "none kept": []}, {"kept": 0, "none kept": 0}, True
        for index in range(1, episodes + 1):
            outcomes = {}
            for way, kept in (("kept", default), ("none kept", 0)):
                seconds, solved, outcomes[way] = run(rollouts, taus[index : index + 1], kept)
                times[way].append(round(seconds, 3))
                solves[way] += solved
            same &= outcomes["kept"] == outcomes["none kept"]
    finally:
        arm_module.IK_ANSWERS_KEPT = default
    return {
        "benchmark": "ik_answers",
        "task": name,
        "robot": "aila",
        "episodes": episodes,
        "answers_kept": default,
        "process_s": times,
        "solves": solves,
        "ratio_kept_to_none": round(sum(times["kept"]) / sum(times["none kept"]), 3),
        "same_outcomes": same,
    }


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--json", action="store_true")
    parser.add_argument("--task", default="stack", choices=["sort", "stack", "handover"])
    parser.add_argument("--episodes", type=int, default=3)
    args = parser.parse_args()
    report = measure(args.task, args.episodes)
    if args.json:
        print(json.dumps(report, indent=2))
        return
    times, solves = report["process_s"], report["solves"]
    outcomes = "the same" if report["same_outcomes"] else "DIFFERENT"
    print(
        f"{args.task}, {args.episodes} runs of its learned tree on AILA: processor time with the IK answers "
        f"kept {sum(times['kept']):.2f} s ({solves['kept']} solves), with none kept "
        f"{sum(times['none kept']):.2f} s ({solves['none kept']} solves): "
        f"ratio {report['ratio_kept_to_none']:.3f}; outcomes {outcomes}"
    )


if __name__ == "__main__":
    main()
