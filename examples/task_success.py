"""A task's success rate: its demo (default tree) run at a range of seeds on each robot it fits, judged by
the task's own rule; one line per run, a summary per robot, and JSON with ``--json``.

    python examples/task_success.py stack --seeds 100-109 [--robots aila ur5e openarm] [--json]

The figures of docs/demos.md that are not covered by a test's seeds come from here.
"""

from __future__ import annotations

import argparse
import json

import besman.robots as robots
from besman.tasks import task
from besman.tasks.running import run_demo


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
    parser.add_argument("--json", action="store_true")
    args = parser.parse_args()
    chosen = task(args.task)
    fitting = [name for name in robots.available() if chosen.fits(robots.describe(name))]
    report = {"task": chosen.name, "seeds": [args.seeds.start, args.seeds.stop - 1], "robots": {}}
    for robot in args.robots or fitting:
        runs = []
        for seed in args.seeds:
            summary = run_demo(chosen.name, seed, robot=robot)
            runs.append({"seed": seed, "success": summary.success, "outcome": summary.outcome})
            if not args.json:
                print(f"{robot} {seed}: {'SUCCESS' if summary.success else 'FAILURE'}: {summary.outcome}")
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


if __name__ == "__main__":
    main()
