"""The behaviour-tree runner's cost: overhead per tick and real-time factor of grasp-then-place.

    python benchmarks/trees.py [--json] [--runs 3]

The overhead per tick is the median wall time of ticking the tree and recording the tick (the log) (the
longest ticks are those that plan motions, reported apart), without the
executor's control cycles and physics in between; the real-time factor is simulated time / wall time of
whole runs (viewer off).
"""

from __future__ import annotations

import argparse
import json
import statistics

from besman.trees import grasp_then_place
from besman.trees.runner import tabletop_run


def measure(runs: int) -> dict:
    per_tick, records, planning, factors = [], [], [], []
    for seed in range(runs):
        runner, _ = tabletop_run(
            grasp_then_place(), {"object": (0.55, -0.08), "place": (0.54, -0.41)}, seed=seed
        )
        result = runner.run()
        per_tick.append(1e6 * statistics.median(runner.tick_seconds))
        records.append(1e6 * statistics.median(runner.record_seconds))
        planning.append(1e3 * max(runner.tick_seconds))
        factors.append(result.sim_time_s / result.wall_time_s)
    return {
        "runs": runs,
        "tick_us": statistics.median(per_tick),
        "record_us": statistics.median(records),
        "overhead_per_tick_us": statistics.median(per_tick) + statistics.median(records),
        "longest_tick_ms": statistics.median(planning),
        "tick_period_us": 1e6 / 50.0,
        "real_time_factor": statistics.median(factors),
    }


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--json", action="store_true")
    parser.add_argument("--runs", type=int, default=3)
    args = parser.parse_args()
    report = measure(args.runs)
    if args.json:
        print(json.dumps({"benchmark": "trees", **report}, indent=2))
        return
    print(
        f"runner overhead per tick: {report['overhead_per_tick_us']:.0f} us (tree {report['tick_us']:.0f} us "
        f"+ log {report['record_us']:.0f} us) per 20 ms of simulated time; longest (planning) tick "
        f"{report['longest_tick_ms']:.0f} ms"
    )
    print(f"grasp-then-place real-time factor: {report['real_time_factor']:.1f}x (viewer off)")


if __name__ == "__main__":
    main()
