"""Grasp-then-place as a behaviour tree against raw physics: real-time factors side by side, and the
runner's overhead per tick.

    python benchmarks/trees.py [--json] [--runs 3]

In one run, on the same scene (AILA's tabletop with the box on the table): the real-time factor (simulated /
wall time) of raw ``mj_step`` with the robot holding still, and of whole grasp-then-place runs of the tree
(perception, planning, Ruckig execution, the tree and its log; viewer off). Their ratio is the claim:
execution costs at most ~3x the physics (target >= 0.3). Raw physics is measured right before and after each
run (the machine's load changes); the ratio is the median over runs of run / raw. The overhead per tick
is the median wall time of
ticking the tree and recording the tick, without the control cycles and physics between ticks; the
longest ticks are those that plan motions, reported apart.
"""

from __future__ import annotations

import argparse
import json
import statistics
import time

import mujoco

from besman.sim.world import tabletop_world
from besman.tasks.running import prepare
from besman.trees import grasp_then_place

# pick and place's 6 cm box at the task's default configuration (the seeds draw its mass and friction)
SETTINGS = {
    "object": (0.55, -0.08, 0.0),
    "place": (0.54, -0.41, 0.0),
    "shape": (0,),
    "size": (0.06, 0.06, 0.06),
}
RAW_SECONDS = 10.0  # simulated seconds of raw stepping per measurement
TARGET_RATIO = 0.3


def raw_real_time_factor() -> float:
    """Simulated / wall time of ``mj_step`` alone on the tabletop scene, the robot holding its home pose."""
    world = tabletop_world()
    world.place_on("box", "table", *SETTINGS["object"])
    steps = round(RAW_SECONDS / world.model.opt.timestep)
    start = time.perf_counter()
    for _ in range(steps):
        mujoco.mj_step(world.model, world.data)
    return RAW_SECONDS / (time.perf_counter() - start)


def measure(runs: int) -> dict:
    per_tick, records, planning, factors, raw, ratios = [], [], [], [], [], []
    for seed in range(runs):
        before = raw_real_time_factor()
        runner = prepare("pick-place", grasp_then_place(), values=SETTINGS, seed=seed).runner
        result = runner.run()
        after = raw_real_time_factor()  # raw physics on both sides of each run: both see the same load
        if result.status != "SUCCESS":
            raise RuntimeError(f"grasp-then-place failed: {result.failed_node}: {result.message}")
        per_tick.append(1e6 * statistics.median(runner.tick_seconds))
        records.append(1e6 * statistics.median(runner.record_seconds))
        planning.append(1e3 * max(runner.tick_seconds))
        factors.append(result.sim_time_s / result.wall_time_s)
        raw.append((before + after) / 2)
        ratios.append(factors[-1] / raw[-1])
    return {
        "runs": runs,
        "tick_us": statistics.median(per_tick),
        "record_us": statistics.median(records),
        "overhead_per_tick_us": statistics.median(per_tick) + statistics.median(records),
        "longest_tick_ms": statistics.median(planning),
        "tick_period_us": 1e6 / 50.0,
        "real_time_factor": statistics.median(factors),
        "raw_mj_step_real_time_factor": statistics.median(raw),
        "ratio_to_raw": statistics.median(ratios),
        "ratios_to_raw": ratios,
        "target_ratio_to_raw": TARGET_RATIO,
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
        f"grasp-then-place real-time factor: {report['real_time_factor']:.1f}x; "
        f"raw mj_step on the same scene "
        f"{report['raw_mj_step_real_time_factor']:.1f}x; ratio {report['ratio_to_raw']:.2f} "
        f"(target >= {TARGET_RATIO}; viewer off)"
    )
    print(
        f"runner overhead per tick: {report['overhead_per_tick_us']:.0f} us (tree {report['tick_us']:.0f} us "
        f"+ log {report['record_us']:.0f} us) per 20 ms of simulated time; longest (planning) tick "
        f"{report['longest_tick_ms']:.0f} ms"
    )


if __name__ == "__main__":
    main()
