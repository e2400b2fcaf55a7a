"""Puck strike on the UR5e: a demonstration, a scripted baseline and CMA-ES from the imitated demonstration.

    python benchmarks/puck_strike.py [--json] [--held-out 50] [--seeds 5] [--budget 150] [--sigma 0.1]
                                     [--tau 1.55,0.135]
    python benchmarks/puck_strike.py --write-demo      # rewrites examples/data/puck_strike_demo.json

1. The demonstration (``examples/data/puck_strike_demo.json``, a synthetic kinesthetic-style strike that
   stops short on purpose: :mod:`besman.tasks.puck_strike.demonstration`) is imitated into the task's 72-D
   DMP; the imitated DMP and the recording replayed as it is run on ``--held-out`` targets (a Latin
   hypercube over the task's box, seed 1).
2. The scripted baseline (:mod:`besman.tasks.puck_strike.baseline`: aimed along the line from the puck to
   the target, the textbook's contact speed, Ruckig moves at the arm's limits) runs on the same targets; so
   does the same planner with the puck's exit speed per the blade's measured once, from one strike at the
   middle of the box (a planner with one learned number).
3. CMA-ES (``make_optimizer("cmaes", WarmStart(imitated theta, --sigma))``, the default population) refines
   the imitated DMP for one target (``--tau``, the middle of the box by default), one search per seed
   (0 .. ``--seeds`` - 1) in lockstep, until a rollout succeeds or ``--budget`` rollouts: the rollouts to
   the first success per seed (the start mean is not counted), then each search's best theta on the
   held-out targets (a theta learned for one target is expected to succeed only near it).

Everything is seeded and the rollouts are deterministic: the same command prints the same numbers. The
default run takes about a minute on two cores.
"""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
from open_loop_benchmark import arguments, cmaes, everywhere, outcomes, replayed

from besman.tasks import task as registered
from besman.tasks.puck_strike.baseline import calibrated_exit_ratio, scripted_baseline
from besman.tasks.puck_strike.demonstration import (
    FILE,
    imitate,
    load_demonstration,
    save_demonstration,
    synthetic_strike,
)
from besman.tasks.puck_strike.rollouts import PuckStrikeRollouts

DEMO = Path(__file__).resolve().parents[1] / "examples" / "data" / FILE
MIDDLE = (1.55, 0.135)


def held_out_taus(count: int, seed: int = 1) -> np.ndarray:
    return registered("puck-strike").spread("ur5e", count, seed)


def strikes(evaluation, **more) -> dict:
    """The outcome counts, with the median miss (m), and ``more``."""
    misses = [d.distance for d in evaluation.details if d.distance is not None]
    return outcomes(evaluation, median_miss_m=round(float(np.median(misses)), 4) if misses else None) | more


def run(held_out: int, seeds: int, budget: int, tau, sigma: float) -> dict:
    task = PuckStrikeRollouts()
    taus = held_out_taus(held_out)
    times, positions = load_demonstration(DEMO)
    theta = imitate(task, times, positions)
    report: dict = {"benchmark": "puck_strike", "robot": "ur5e", "dimensions": task.n_params}
    report["held_out_targets"] = {
        "count": held_out,
        "seed": 1,
        "x_range_m": [float(taus[:, 0].min()), float(taus[:, 0].max())],
        "y_range_m": [float(taus[:, 1].min()), float(taus[:, 1].max())],
    }

    steps = np.arange(task.n_steps + 1) * task.timestep
    _, replay_q, replay_v = synthetic_strike(task.start, steps)
    replay = replayed(task, replay_q, replay_v, taus)
    report["demonstration_replayed"] = strikes(replay, rest=list(replay.details[0].rest))
    imitated = everywhere(task, theta, taus)
    report["demonstration_imitated"] = strikes(imitated, rest=list(imitated.details[0].rest))
    report["scripted_baseline"] = strikes(scripted_baseline(task, taus))
    ratio = calibrated_exit_ratio(task, MIDDLE)
    report["scripted_baseline_calibrated"] = strikes(
        scripted_baseline(task, taus, ratio), exit_ratio=round(ratio, 4), calibration_rollouts=1
    )

    target = np.asarray(tau, dtype=float)
    start = task.evaluate(theta, target).details[0]
    report["cmaes"] = cmaes(
        task,
        theta,
        target,
        taus,
        sigma=sigma,
        seeds=seeds,
        budget=budget,
        tau={"tau_target_m": target.tolist()},
        start={"start_rest": list(start.rest)},
        with_mean=True,
    )
    task.close()
    return report


def main() -> None:
    args = arguments(
        __doc__,
        budget=150,
        sigma=0.1,
        tau=",".join(map(str, MIDDLE)),
        tau_help="target x,y (m) CMA-ES refines at",
    )
    if args.write_demo:
        task = PuckStrikeRollouts()
        print(save_demonstration(DEMO, task.start, task.arm.joints))
        return
    tau = [float(value) for value in args.tau.split(",")]
    report = run(args.held_out, args.seeds, args.budget, tau, args.sigma)
    if args.json:
        print(json.dumps(report, indent=2))
        return
    held = report["held_out_targets"]
    print(f"held-out targets: {held['count']}, x in {held['x_range_m']} m, y in {held['y_range_m']} m")
    for key in (
        "demonstration_replayed",
        "demonstration_imitated",
        "scripted_baseline",
        "scripted_baseline_calibrated",
    ):
        o = report[key]
        print(
            f"{key:29s} success {o['successes']}/{o['rollouts']} ({o['success_rate']:.0%}); median miss "
            f"{o['median_miss_m']} m"
            + (f"; exit ratio {o['exit_ratio']}" if "exit_ratio" in o else "")
            + (f"; its puck rests at {o['rest']}" if "rest" in o else "")
        )
    c = report["cmaes"]
    print(
        f"CMA-ES at {c['tau_target_m']} from the imitated demonstration (start reward "
        f"{c['start_reward']:.3f}, "
        f"puck at {c['start_rest']}), sigma {c['sigma']}: rollouts to the first success per seed "
        f"{c['rollouts_to_first_success']} (mean {c['mean_rollouts_to_first_success']}), {c['seconds']} s; "
        f"its best thetas succeed on {c['best_thetas_on_held_out']} of the held-out targets"
    )


if __name__ == "__main__":
    main()
