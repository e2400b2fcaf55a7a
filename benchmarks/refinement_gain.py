"""Does refinement pay on pick and place? The refined pool against the imitation-only one on the whole
task's cost, and the learned tree's first attempt against the scripted tree's, on held-out perturbed tasks.

    python benchmarks/refinement_gain.py [--json] [--robots aila] [--count 200] [--seeds 0 1 2]
                                         [--seed 2028] [--workers 2] [--work DIR]
                                         [--out docs/results/refinement_gain.json]

Pools: per training seed s, ``besman learn`` with its defaults and ``--seed s`` on the 15 shared recordings
(seed 0 is the committed ``examples/pools/pick_place_<robot>``; the others are learned into ``--work``).
The imitation-only pool is the retargeted shapes as they are: its templates would hold the shape at every
training task, so it predicts the shape everywhere.

Held-out tasks: ``count`` taus drawn as ``benchmarks/learned.py`` draws them (positions and yaws over the
task's box, sizes no training task of any pool had); task k perturbed with its own seed (a child of
``--seed``): perception errors at every look, and the even half pushed during the reach.

- **Whole-task cost** (the refinement's own measure: per block its duration, path, peak jerk, joint margin
  and collisions, plus the failure's cost where the task failed in it, summed over the blocks that ran), on
  one whole-task rollout per task with no retry (:class:`~besman.tasks.pick_place.sequence.SequenceRollouts`,
  the plan's default subgoals): the imitation-only shapes, and per seed each block's template instantiated
  at the task (its input: the hand's planned move). Paired per task; the ratio of the means with a 95 %
  bootstrap interval over the tasks.
- **First-attempt success** (the task succeeded with one reach and one carry, no try failed), through
  besman's runner: per seed the pool's learned ``tree.yaml``, and the scripted tree with nothing learned
  (``examples/trees/grasp_then_place.yaml``), the same seeds (mass, friction, perturbations) for both;
  Wilson intervals, and the difference with a paired bootstrap interval.

The issue's bars (54, item 2): cost ratio <= 0.8, first attempt >= +10 points over the scripted tree.
JSON to ``--out`` (and stdout with ``--json``), the figure beside it (``.png``).
"""

from __future__ import annotations

import argparse
import json
import multiprocessing
import subprocess
import sys
import time
from concurrent.futures import ProcessPoolExecutor
from pathlib import Path

import numpy as np
from learned import held_out, training_taus
from learned_tree import episode

from besman.core.seeds import child_seed
from besman.skills import SkillTemplatePool

ROOT = Path(__file__).resolve().parent.parent
RECORDINGS = ROOT.parent / "shared" / "data" / "dfki_pick_and_place"
SCRIPTED = ROOT / "examples" / "trees" / "grasp_then_place.yaml"
BLOCKS = ("reach", "carry", "return")
EPISODES, BOOTSTRAP = 2, 3  # children of --seed: the tasks' perturbations, the bootstrap's draws
RESAMPLES = 2000
COST_BAR, SUCCESS_BAR = 0.8, 0.10


def pool_of(robot: str, seed: int, work: Path) -> Path:
    """The pool learned with ``seed`` (the committed one for seed 0), learned into ``work`` if absent."""
    if seed == 0:
        return ROOT / "examples" / "pools" / f"pick_place_{robot}"
    out = work / f"{robot}-seed{seed}"
    if not (out / "tree.yaml").is_file():
        command = [sys.executable, "-m", "besman", "learn", "--demos", str(RECORDINGS), "--robot", robot]
        subprocess.run([*command, "--seed", str(seed), "--out", str(out)], check=True)
    return out


def rollouts_chunk(arguments: tuple) -> list[tuple[float, bool]]:
    """Whole-task rollouts (cost, success) of one theta source on ``taus``: the shapes (``pool`` None) or
    each block's template at the task."""
    from besman.sim.manipulation import PlanningError
    from besman.tasks.pick_place.sequence import SUBGOALS, SequenceConfig, SequenceRollouts

    robot, shapes, pool, taus, seeds = arguments
    config = SequenceConfig(robot, tuple(str(Path(shapes) / f"{block}.json") for block in BLOCKS))
    rollouts = SequenceRollouts(config)
    start = rollouts.start()
    templates = None if pool is None else SkillTemplatePool(pool)
    inputs = {}
    if templates is not None:
        from besman.tasks import task

        blocks = task("pick-place").building_blocks(robot)
        inputs = {b: blocks.refinement(b, str(Path(shapes) / f"{b}.json")).build() for b in BLOCKS}
    found = []
    for index, (tau, seed) in enumerate(zip(taus, seeds, strict=True)):
        parts = list(start)
        if templates is not None:
            for k, (block, mask) in enumerate(zip(BLOCKS, rollouts.masks, strict=True)):
                try:
                    mean, _ = templates[block].predict(inputs[block].input(tau))
                except PlanningError:  # no planned move to take the input from: the rollout fails on it too
                    continue
                parts[k] = np.r_[mean[mask], np.zeros(len(SUBGOALS[block]))]
        outcome = rollouts.rollout(np.concatenate(parts), np.r_[tau, seed, index % 2 == 0])
        found.append((float(np.nansum(outcome.costs)), bool(outcome.success)))
    return found


def wilson(successes: int, runs: int, z: float = 1.96) -> list[float]:
    """The 95 % Wilson interval of a success rate."""
    p = successes / runs
    middle = (p + z * z / (2 * runs)) / (1 + z * z / runs)
    half = z * np.sqrt(p * (1 - p) / runs + z * z / (4 * runs * runs)) / (1 + z * z / runs)
    return [float(middle - half), float(middle + half)]


def bootstrap(statistic, arrays: tuple[np.ndarray, ...], seed: int) -> list[float]:
    """The 95 % percentile interval of ``statistic`` over tasks resampled with replacement (paired)."""
    rng = np.random.default_rng(seed)
    n = len(arrays[0])
    draws = [statistic(*(a[picks] for a in arrays)) for picks in rng.integers(0, n, (RESAMPLES, n))]
    return [float(np.percentile(draws, 2.5)), float(np.percentile(draws, 97.5))]


def ratio(refined: np.ndarray, imitation: np.ndarray) -> float:
    return refined.mean() / imitation.mean()


def gain(learned: np.ndarray, scripted: np.ndarray) -> float:
    return learned.mean() - scripted.mean()


def measure(robot: str, args: argparse.Namespace) -> dict:
    started = time.time()
    pools = {seed: pool_of(robot, seed, args.work) for seed in args.seeds}
    trained = np.concatenate([training_taus(SkillTemplatePool(p)) for p in pools.values()])
    taus, sizes = held_out(robot, trained, args.count, args.seed)
    seeds = [child_seed(args.seed, EPISODES, k) % 2**31 for k in range(args.count)]
    shapes = pools[args.seeds[0]] / "work" / "shapes"
    sources = {"imitation": None, **{f"seed {s}": str(p) for s, p in pools.items()}}
    chunks = np.array_split(np.arange(args.count), max(1, args.workers * 4))
    jobs = [
        (robot, str(shapes), pool, taus[c], [seeds[k] for k in c])
        for pool in sources.values()
        for c in chunks
    ]
    trees = {"scripted": SCRIPTED, **{f"seed {s}": p / "tree.yaml" for s, p in pools.items()}}
    episodes = [
        (str(tree), robot, tau, seeds[k], "push" if k % 2 == 0 else "perception")
        for tree in trees.values()
        for k, tau in enumerate(taus)
    ]
    context = multiprocessing.get_context("spawn")
    with ProcessPoolExecutor(args.workers, mp_context=context) as executor:
        rolled = [row for chunk in executor.map(rollouts_chunk, jobs) for row in chunk]
        runs = list(executor.map(episode, episodes, chunksize=4))
    n = args.count
    costs = {name: np.array([c for c, _ in rolled[i * n : (i + 1) * n]]) for i, name in enumerate(sources)}
    rolled_success = {name: [s for _, s in rolled[i * n : (i + 1) * n]] for i, name in enumerate(sources)}
    first = {
        name: np.array([r["first_attempt"] for r in runs[i * n : (i + 1) * n]])
        for i, name in enumerate(trees)
    }
    success = {
        name: np.array([r["success"] for r in runs[i * n : (i + 1) * n]]) for i, name in enumerate(trees)
    }
    seeds_report = {}
    for s in args.seeds:
        name = f"seed {s}"
        cost_ratio = float(ratio(costs[name], costs["imitation"]))
        first_gain = float(gain(first[name], first["scripted"]))
        seeds_report[name] = {
            "pool": str(Path(pools[s]).relative_to(ROOT))
            if Path(pools[s]).is_relative_to(ROOT)
            else str(pools[s]),
            "cost": float(costs[name].mean()),
            "cost_ratio": cost_ratio,
            "cost_ratio_interval": bootstrap(
                ratio, (costs[name], costs["imitation"]), child_seed(args.seed, BOOTSTRAP, s)
            ),
            "rollout_success": int(sum(rolled_success[name])),
            "first_attempt": int(first[name].sum()),
            "first_attempt_interval": wilson(int(first[name].sum()), n),
            "task_success": int(success[name].sum()),
            "first_attempt_gain": first_gain,
            "first_attempt_gain_interval": bootstrap(
                gain,
                (first[name].astype(float), first["scripted"].astype(float)),
                child_seed(args.seed, BOOTSTRAP, s),
            ),
            "meets_cost_bar": cost_ratio <= COST_BAR,
            "meets_first_attempt_bar": first_gain >= SUCCESS_BAR,
        }
    return {
        "sizes": sizes,
        "imitation": {
            "cost": float(costs["imitation"].mean()),
            "rollout_success": int(sum(rolled_success["imitation"])),
        },
        "scripted": {
            "tree": str(SCRIPTED.relative_to(ROOT)),
            "first_attempt": int(first["scripted"].sum()),
            "first_attempt_interval": wilson(int(first["scripted"].sum()), n),
            "task_success": int(success["scripted"].sum()),
        },
        "seeds": seeds_report,
        "minutes": round((time.time() - started) / 60, 1),
    }


def plot(results: dict, path: Path) -> None:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    robots = list(results["robots"])
    figure, (cost_axis, first_axis) = plt.subplots(1, 2, figsize=(10, 4))
    for r, robot in enumerate(robots):
        found = results["robots"][robot]
        for s, (name, entry) in enumerate(found["seeds"].items()):
            x = r + 0.2 * (s - 1)
            low, high = entry["cost_ratio_interval"]
            cost_axis.errorbar(
                x,
                entry["cost_ratio"],
                [[entry["cost_ratio"] - low], [high - entry["cost_ratio"]]],
                fmt="o",
                color=f"C{s}",
                label=name if r == 0 else None,
            )
            low, high = entry["first_attempt_gain_interval"]
            gain = 100 * entry["first_attempt_gain"]
            first_axis.errorbar(x, gain, [[gain - 100 * low], [100 * high - gain]], fmt="o", color=f"C{s}")
    cost_axis.axhline(COST_BAR, color="k", linestyle="--", label=f"bar {COST_BAR}")
    cost_axis.axhline(1.0, color="grey", linewidth=0.5)
    first_axis.axhline(100 * SUCCESS_BAR, color="k", linestyle="--")
    first_axis.axhline(0.0, color="grey", linewidth=0.5)
    for axis, label in (
        (cost_axis, "whole-task cost, refined / imitation-only"),
        (first_axis, "first attempt, learned - scripted (points)"),
    ):
        axis.set_xticks(range(len(robots)), robots)
        axis.set_ylabel(label)
    cost_axis.legend(fontsize=8)
    figure.suptitle(f"{results['count']} held-out perturbed tasks, 95 % intervals")
    figure.tight_layout()
    figure.savefig(path, dpi=120)


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--json", action="store_true", help="print the results as JSON")
    parser.add_argument("--robots", nargs="+", default=["aila"])
    parser.add_argument("--count", type=int, default=200, help="held-out tasks")
    parser.add_argument("--seeds", type=int, nargs="+", default=[0, 1, 2], help="training seeds")
    parser.add_argument("--seed", type=int, default=2028, help="draws the held-out tasks and perturbations")
    parser.add_argument("--workers", type=int, default=2)
    parser.add_argument("--work", type=Path, default=ROOT / "build" / "refinement_gain")
    parser.add_argument("--out", type=Path, default=ROOT / "docs" / "results" / "refinement_gain.json")
    args = parser.parse_args(argv)
    if args.count < 2 or any(s < 0 for s in args.seeds):
        parser.error("--count must be at least 2 and the seeds whole numbers >= 0")
    results = {
        "count": args.count,
        "seed": args.seed,
        "bars": {"cost_ratio": COST_BAR, "first_attempt_gain": SUCCESS_BAR},
        "robots": {robot: measure(robot, args) for robot in args.robots},
    }
    args.out.parent.mkdir(parents=True, exist_ok=True)
    args.out.write_text(json.dumps(results, indent=1) + "\n")
    plot(results, args.out.with_suffix(".png"))
    if args.json:
        print(json.dumps(results, indent=1))
    for robot, found in results["robots"].items():
        print(
            f"{robot}: imitation-only cost {found['imitation']['cost']:.3f}, scripted first attempt "
            f"{found['scripted']['first_attempt']}/{args.count}"
        )
        for name, entry in found["seeds"].items():
            low, high = entry["cost_ratio_interval"]
            g_low, g_high = entry["first_attempt_gain_interval"]
            print(
                f"  {name}: cost ratio {entry['cost_ratio']:.3f} [{low:.3f}, {high:.3f}] (bar {COST_BAR}), "
                f"first attempt {entry['first_attempt']}/{args.count}, "
                f"{100 * entry['first_attempt_gain']:+.1f} points [{100 * g_low:+.1f}, {100 * g_high:+.1f}] "
                f"(bar +{100 * SUCCESS_BAR:.0f})"
            )
    return 0


if __name__ == "__main__":
    sys.exit(main())
