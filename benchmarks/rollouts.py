"""Rollout speed on the throwing task, side by side in one run, and the executor's real-time factor.

    python benchmarks/rollouts.py [--json] [--repeats 7]

Throwing (64 candidates x 1.5 s at 1 ms, all threads of this machine):
- ours: ``ThrowingRollouts.evaluate`` - DMP generation, controls, rollouts, landing points and rewards;
- raw: ``mujoco.rollout`` alone on the same control arrays (the physical limit here);
- naive: a Python loop over ``mj_step`` on one thread, setting the same controls each step.
Targets: ours >= 0.9 x raw steps/s, ours >= 1.8 x naive steps/s.

Pick-and-place (AILA, viewer off): simulated time / wall time of whole scripted episodes (planning
included), target >= 5.

Block rollouts (what ``besman learn`` refines: the committed pool's learned reach, four tasks, one process):
``Executor.run`` in chunks of up to ``RUN_CHUNK`` cycles inside which no motion can succeed (the default)
against cycle by cycle; the rewards must be the same, target >= 1.5x.
"""

from __future__ import annotations

import argparse
import json
import os
import statistics
import time
from pathlib import Path

import mujoco
import numpy as np
from mujoco import rollout
from rich.console import Console
from rich.table import Table

from besman.sim import executor
from besman.tasks.pick_place.blocks import BlockTaskConfig
from besman.tasks.pick_place.episode import PickPlaceRollouts
from besman.tasks.throwing.rollouts import ThrowingConfig, ThrowingRollouts

CANDIDATES = 64
POOL = Path(__file__).resolve().parents[1] / "examples" / "pools" / "pick_place_aila"
REACH = POOL / "work" / "shapes" / "reach.json"  # the learned reach's joint-space shape


def timed(functions, repeats: int) -> list[float]:
    """Median wall time of each function, measured in alternation so that machine noise hits all alike."""
    for function in functions:
        function()  # warm-up: thread pools, caches
    samples = [[] for _ in functions]
    for _ in range(repeats):
        for function, times in zip(functions, samples, strict=True):
            start = time.perf_counter()
            function()
            times.append(time.perf_counter() - start)
    return [statistics.median(times) for times in samples]


def throwing(repeats: int) -> dict:
    task = ThrowingRollouts(ThrowingConfig(duration=1.5))
    rng = np.random.default_rng(0)
    thetas = np.tile(task.default_theta(), (CANDIDATES, 1))
    joints = task.arm.size * (task.config.n_weights + 2)  # perturb the joints' DMPs; every throw releases
    thetas[:, :joints] += 0.05 * rng.normal(size=(CANDIDATES, joints))
    taus = np.tile([-3.5, -3.6], (CANDIDATES, 1))
    controls, failures, _, _ = task.controls(thetas)
    if any(failures):
        raise RuntimeError(f"benchmark candidates must all be simulated: {failures}")
    steps = CANDIDATES * task.n_steps
    initial = np.repeat(task._initial_state[None], CANDIDATES, axis=0)
    datas = [mujoco.MjData(task.model) for _ in range(os.cpu_count() or 1)]

    def raw_rollout():  # the library's plain call, one MjData per thread
        rollout.rollout(
            task.model,
            datas,
            initial,
            controls,
            control_spec=task._control_spec,
            initial_warmstart=np.zeros((CANDIDATES, task.model.nv)),
        )

    ours, raw = timed([lambda: task.evaluate(thetas, taus), raw_rollout], repeats)

    model, data = task.model, mujoco.MjData(task.model)
    spec = mujoco.mjtState.mjSTATE_FULLPHYSICS.value

    def naive():
        for candidate in controls:
            mujoco.mj_resetData(model, data)
            mujoco.mj_setState(model, data, task._initial_state, spec)
            for control in candidate:
                data.ctrl[:] = control[:-1]
                data.eq_active[task.weld] = control[-1]
                mujoco.mj_step(model, data)

    (loop,) = timed([naive], max(1, repeats // 3))
    return {
        "candidates": CANDIDATES,
        "steps": steps,
        "threads": os.cpu_count(),
        "ours_steps_per_s": steps / ours,
        "raw_rollout_steps_per_s": steps / raw,
        "naive_loop_steps_per_s": steps / loop,
        "ours_vs_raw": raw / ours,
        "ours_vs_naive": loop / ours,
        "targets": {"ours_vs_raw": 0.9, "ours_vs_naive": 1.8},
    }


def pick_and_place() -> dict:
    task = PickPlaceRollouts()
    box = (0.0, 0.06, 0.06, 0.06)  # pick and place's 6 cm box; every yaw 0
    taus = [
        [0.5, -0.1, 0.0, 0.5, -0.4, 0.0, *box],
        [0.6, -0.05, 0.0, 0.58, -0.45, 0.0, *box],
        [0.55, -0.12, 0.0, 0.47, -0.36, 0.0, *box],
    ]
    start = time.perf_counter()
    details = [task.episode(tau) for tau in taus]
    wall = time.perf_counter() - start
    simulated = sum(detail.sim_time for detail in details)
    return {
        "episodes": len(taus),
        "succeeded": sum(detail.success for detail in details),
        "simulated_s": simulated,
        "wall_s": wall,
        "real_time_factor": simulated / wall,
        "target": 5.0,
    }


def block_rollouts(repeats: int) -> dict:
    task = BlockTaskConfig("reach", str(REACH)).build()
    box = (0.54, -0.41, 0.0, 0.0, 0.06, 0.06, 0.06)  # the place and pick and place's 6 cm box
    taus = np.array([[x, y, 0.0, *box] for x, y in ((0.5, -0.1), (0.6, -0.05), (0.55, -0.12), (0.47, -0.02))])
    thetas = np.tile(task.shape.theta, (len(taus), 1))

    def chunked():
        return task.evaluate_locally(thetas, taus).rewards

    def cycle_by_cycle():
        chunk, executor.RUN_CHUNK = executor.RUN_CHUNK, 1
        try:
            return task.evaluate_locally(thetas, taus).rewards
        finally:
            executor.RUN_CHUNK = chunk

    fast, slow = timed([chunked, cycle_by_cycle], repeats)
    return {
        "rollouts": len(taus),
        "chunked_s": fast,
        "cycle_by_cycle_s": slow,
        "speedup": slow / fast,
        "same_rewards": bool(np.array_equal(chunked(), cycle_by_cycle())),
        "target": 1.5,
    }


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--json", action="store_true", help="print JSON instead of tables")
    parser.add_argument("--repeats", type=int, default=7)
    args = parser.parse_args()
    report = {
        "benchmark": "rollouts",
        "throwing": throwing(args.repeats),
        "pick_and_place": pick_and_place(),
        "block_rollouts": block_rollouts(max(1, args.repeats // 3)),
    }
    if args.json:
        print(json.dumps(report, indent=2))
        return
    throw, place = report["throwing"], report["pick_and_place"]
    table = Table(title=f"Throwing: {CANDIDATES} candidates x 1.5 s, {throw['threads']} threads")
    for column in ("", "steps/s", "ours / this", "target"):
        table.add_column(column, justify="right")
    table.add_row("ours (DMPs + rollout + reward)", f"{throw['ours_steps_per_s']:,.0f}", "", "")
    table.add_row(
        "raw mujoco.rollout",
        f"{throw['raw_rollout_steps_per_s']:,.0f}",
        f"{throw['ours_vs_raw']:.2f}x",
        ">= 0.9x",
    )
    table.add_row(
        "naive mj_step loop",
        f"{throw['naive_loop_steps_per_s']:,.0f}",
        f"{throw['ours_vs_naive']:.2f}x",
        ">= 1.8x",
    )
    console = Console()
    console.print(table)
    console.print(
        f"Pick-and-place: {place['succeeded']}/{place['episodes']} episodes, {place['simulated_s']:.1f} s "
        f"simulated in {place['wall_s']:.1f} s: real-time factor {place['real_time_factor']:.1f}x "
        "(target >= 5x)"
    )
    blocks = report["block_rollouts"]
    console.print(
        f"Block rollouts ({blocks['rollouts']} reaches): in chunks {blocks['chunked_s']:.2f} s, cycle by "
        f"cycle {blocks['cycle_by_cycle_s']:.2f} s: {blocks['speedup']:.2f}x (target >= 1.5x), same "
        f"rewards: {blocks['same_rewards']}"
    )


if __name__ == "__main__":
    main()
