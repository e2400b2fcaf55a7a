"""Ball-in-a-cup on the UR5e: a demonstration, a scripted baseline and CMA-ES from the imitated demonstration.

    python benchmarks/ball_in_cup.py [--json] [--held-out 50] [--seeds 5] [--budget 400] [--tau 0.375]
    python benchmarks/ball_in_cup.py --write-demo      # rewrites examples/data/ball_in_cup_demo.json

1. The demonstration (``examples/data/ball_in_cup_demo.json``, a synthetic kinesthetic-style swing that
   misses on purpose: :mod:`besman.tasks.ball_in_cup.demonstration`) is imitated into the task's 72-D DMP;
   the imitated DMP and the recording replayed as it is run on ``--held-out`` string lengths (a Latin
   hypercube over the task's box, seed 1).
2. The scripted baseline (:mod:`besman.tasks.ball_in_cup.baseline`) runs on the same string lengths.
3. CMA-ES (``make_optimizer("cmaes", WarmStart(imitated theta, --sigma))``, the default population) refines
   the imitated DMP at one string length (``--tau``, the middle of the box by default), one search per seed
   (0 .. ``--seeds`` - 1) in lockstep, until a rollout succeeds or ``--budget`` rollouts: the rollouts to
   the first success per seed (the start mean is not counted), then the best theta of each search on the
   held-out lengths.

Everything is seeded and the rollouts are deterministic: the same command prints the same numbers. The
default run takes about 25 s on two cores.

The skill template over the string length (K = 10 training lengths, zero shot and after <= 10 more rollouts
on the held-out lengths, learning curves and plots) is ``besman experiment ball-in-cup``
(``docs/ball_in_cup.md``).
"""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
from open_loop_benchmark import arguments, cmaes, everywhere, outcomes, replayed

from besman.tasks import task as registered
from besman.tasks.ball_in_cup.baseline import scripted_baseline
from besman.tasks.ball_in_cup.demonstration import (
    FILE,
    imitate,
    load_demonstration,
    save_demonstration,
    synthetic_swing,
)
from besman.tasks.ball_in_cup.rollouts import BallInCupRollouts

DEMO = Path(__file__).resolve().parents[1] / "examples" / "data" / FILE


def held_out_taus(count: int, seed: int = 1) -> np.ndarray:
    return registered("ball-in-cup").spread("ur5e", count, seed)


def catches(evaluation) -> dict:
    """The outcome counts, with how many balls came down through the rim and how far from the axis."""
    crossings = [d.crossing_distance for d in evaluation.details if d.crossing_distance is not None]
    return outcomes(
        evaluation,
        came_down_through_the_rim=len(crossings),
        median_crossing_distance_m=round(float(np.median(crossings)), 4) if crossings else None,
    )


def run(held_out: int, seeds: int, budget: int, tau: float, sigma: float) -> dict:
    task = BallInCupRollouts()
    taus = held_out_taus(held_out)
    times, positions = load_demonstration(DEMO)
    theta = imitate(task, times, positions)
    report: dict = {"benchmark": "ball_in_cup", "robot": "ur5e", "dimensions": task.n_params}
    report["held_out_string_lengths"] = {
        "count": held_out,
        "seed": 1,
        "range_m": [float(taus.min()), float(taus.max())],
    }

    steps = np.arange(task.n_steps + 1) * task.timestep
    _, replay_q, replay_v = synthetic_swing(task.start, steps)
    report["demonstration_replayed"] = catches(replayed(task, replay_q, replay_v, taus))
    report["demonstration_imitated"] = catches(everywhere(task, theta, taus))
    report["scripted_baseline"] = catches(scripted_baseline(task, taus))

    report["cmaes"] = cmaes(
        task,
        theta,
        np.array([tau]),
        taus,
        sigma=sigma,
        seeds=seeds,
        budget=budget,
        tau={"tau_string_length_m": tau},
    )
    task.close()
    return report


def main() -> None:
    args = arguments(
        __doc__, budget=400, sigma=0.3, tau="0.375", tau_help="string length (m) CMA-ES refines at"
    )
    if args.write_demo:
        task = BallInCupRollouts()
        print(save_demonstration(DEMO, task.start, task.arm.joints))
        return
    report = run(args.held_out, args.seeds, args.budget, float(args.tau), args.sigma)
    if args.json:
        print(json.dumps(report, indent=2))
        return
    print(f"held-out string lengths: {args.held_out} in {report['held_out_string_lengths']['range_m']} m")
    for key in ("demonstration_replayed", "demonstration_imitated", "scripted_baseline"):
        o = report[key]
        print(
            f"{key:24s} success {o['successes']}/{o['rollouts']} ({o['success_rate']:.0%}); down through "
            f"the rim {o['came_down_through_the_rim']}, median {o['median_crossing_distance_m']} m from the "
            "axis"
        )
    c = report["cmaes"]
    print(
        f"CMA-ES at {c['tau_string_length_m']} m from the imitated demonstration (start reward "
        f"{c['start_reward']:.3f}): rollouts to the first success per seed {c['rollouts_to_first_success']} "
        f"(median {c['median_rollouts_to_first_success']}), {c['seconds']} s; its best thetas succeed on "
        f"{c['best_thetas_on_held_out']} of the held-out lengths"
    )


if __name__ == "__main__":
    main()
