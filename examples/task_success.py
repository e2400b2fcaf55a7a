"""A task's success rate: its demo (default tree, or ``--tree FILE``) run at a range of seeds on each robot
it fits, judged by the task's own rule; one line per run, a summary per robot, and JSON with ``--json``.
Runs go two at a time in worker processes (each run is independent, so the order does not matter).

    python examples/task_success.py stack --seeds 100-109 [--robots aila ur5e openarm] [--tree FILE] [--json]

The figures of docs/demos.md that are not covered by a test's seeds come from here.
"""

from __future__ import annotations

import argparse
import json
from concurrent.futures import ProcessPoolExecutor
from pathlib import Path

import besman.robots as robots
from besman.tasks import task
from besman.tasks.running import run

WORKERS = 2


def seed_range(text: str) -> range:
    first, _, last = text.partition("-")
    return range(int(first), int(last or first) + 1)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("task")
    parser.add_argument(
        "--seeds", type=seed_range, default=range(100, 110), help="FIRST-LAST (default 100-109)"
    )
    parser.add_argument("--robots", nargs="+", default=None, help="default: every robot the task fits")
    parser.add_argument("--tree", type=Path, default=None, help="a tree file (default: the task's own)")
    parser.add_argument("--json", action="store_true")
    args = parser.parse_args()
    chosen = task(args.task)
    fitting = [name for name in robots.available() if chosen.fits(robots.describe(name))]
    tree = args.tree or chosen.tree_path
    report = {"task": chosen.name, "tree": str(tree), "seeds": [args.seeds.start, args.seeds.stop - 1]}
    report["robots"] = {}
    for robot in args.robots or fitting:
        runs = []
        with ProcessPoolExecutor(WORKERS) as workers:
            jobs = [workers.submit(one_run, chosen.name, tree, robot, seed) for seed in args.seeds]
            for seed, job in zip(args.seeds, jobs, strict=True):
                runs.append(job.result())
                if not args.json:
                    verdict = "SUCCESS" if runs[-1]["success"] else "FAILURE"
                    print(f"{robot} {seed}: {verdict}: {runs[-1]['outcome']}")
        successes = sum(run["success"] for run in runs)
        report["robots"][robot] = {
            "successes": successes,
            "runs": len(runs),
            "failures": [run for run in runs if not run["success"]],
        }
        if not args.json:
            print(f"{robot}: {successes}/{len(runs)}")
    if args.json:
        print(json.dumps(report, indent=2))


def one_run(name: str, tree: Path, robot: str, seed: int) -> dict:
    summary = run(name, tree, robot=robot, seed=seed)
    return {"seed": seed, "success": summary.success, "outcome": summary.outcome}


if __name__ == "__main__":
    main()
