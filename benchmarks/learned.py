"""Grasp-then-place learned from people against grasp-then-place planned by inverse kinematics, side by side.

    python benchmarks/learned.py [--json] [--robot aila] [--pool POOL] [--count 30] [--seed 2026]

On ``count`` task instances tau (object x, y and place x, y) drawn uniformly from the robot's pick-and-place
bounds with ``seed`` (none of them a training task of the pool, which the script checks), three trees run on
the robot's tabletop in MuJoCo, on the task ``pick-place`` (the pool: ``examples/pools/pick_place_<robot>``,
unless given):

- ``ik``: ``examples/trees/grasp_then_place.yaml``, every motion planned (point-to-point reach and
  carry);
- ``zero-shot``: ``examples/trees/grasp_then_place_learned.yaml`` with the templates' means only (online
  refinement off);
- ``refined``: the same tree refining every template instance online first (at most 25 rollouts each in a
  copy of the world), whatever the template's uncertainty.

Per tree: success (the tree succeeded and the task's rule holds: after settling, the box stands upright on
the shelf within 2 cm of the target), mean placement error,
episode time (simulated), the hand's path length and its peak jerk (from the commanded joints,
:func:`besman.sim.blocks.hand_measures`), and the wall time. The learned tree also returns the arm home,
which the IK-planned tree does not, so path and jerk are given twice: up to the placement (what both trees
do: the learned tree's commands before its return home) and over the whole episode. Targets: the learned
tree succeeds in >= 90 % zero-shot and >= 95 % refined, with a mean placement error < 2 cm.
"""

from __future__ import annotations

import argparse
import json
import re
from pathlib import Path

import numpy as np
from tqdm import tqdm

from besman.sim.blocks import hand_measures
from besman.skills import SkillTemplatePool
from besman.tasks import task
from besman.tasks.running import prepare
from besman.trees import load_tree
from besman.trees.files import loads_tree

ROOT = Path(__file__).resolve().parent.parent
TREES = ROOT / "examples" / "trees"
TARGETS = {"zero-shot": 0.90, "refined": 0.95}
MAX_ERROR = 0.02
RETURN = "/return home"  # the learned tree's last subtree: what the IK-planned tree has no counterpart of
THRESHOLD = re.compile(r"refine_above: [0-9.e+-]+")


def trees(pool: Path) -> dict:
    """The three trees (built once; the learned file's refinement threshold set per mode)."""
    text = (TREES / "grasp_then_place_learned.yaml").read_text()
    if not THRESHOLD.search(text):
        raise SystemExit("the learned tree file sets no refine_above; update the benchmark")

    def learned(threshold: str):
        source = THRESHOLD.sub(f"refine_above: {threshold}", text)
        return lambda: loads_tree(source, base=TREES, source="grasp_then_place_learned.yaml", pool=pool)

    return {
        "ik": lambda: load_tree(TREES / "grasp_then_place.yaml"),
        "zero-shot": learned("1.0e9"),
        "refined": learned("0.0"),
    }


def episode(build, tau: np.ndarray, robot: str) -> dict:
    values = {"object": tuple(tau[:2]), "place": tuple(tau[2:])}
    prepared = prepare("pick-place", build(), values=values, robot=robot)
    runner = prepared.runner
    outcome = prepared.judge(runner.run())
    executor = runner.executor
    log, period = executor.log, executor.config.control_period
    placed = log.times <= placing_end(runner)
    whole = hand_measures(executor.arm, log.positions, period)
    to_placement = hand_measures(executor.arm, log.positions[placed], period)
    return {
        "success": outcome.success,
        "placement_error_m": outcome.measurements["placement_error_m"],
        "episode_s": outcome.sim_time_s,
        "wall_s": outcome.wall_time_s,
        "message": outcome.message,
        **whole,
        **{f"{name}_to_placement": value for name, value in to_placement.items()},
    }


def placing_end(runner) -> float:
    """The simulated time at which the tree turned to returning home (the end of the episode for a tree
    that does not): the end of the tick before its return subtree first ran."""
    previous = 0.0
    for record in runner.records:
        if any(path.endswith(RETURN) and status != "INVALID" for path, status in record["statuses"].items()):
            return previous
        previous = record["time"]
    return np.inf


def mean(episodes: list[dict], key: str) -> float:
    return float(np.mean([episode[key] for episode in episodes]))


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--json", action="store_true")
    parser.add_argument("--robot", default="aila", help="the robot (default: aila)")
    parser.add_argument("--pool", default=None, help="the pool (default: the robot's in examples/pools)")
    parser.add_argument("--count", type=int, default=30)
    parser.add_argument("--seed", type=int, default=2026)
    args = parser.parse_args()
    if args.count < 1:
        raise SystemExit(f"--count must be at least 1, got {args.count}")
    bounds = task("pick-place").bounds(args.robot)
    pool_dir = Path(args.pool) if args.pool else ROOT / "examples" / "pools" / f"pick_place_{args.robot}"
    pool = SkillTemplatePool(pool_dir)
    taus = np.random.default_rng(args.seed).uniform(bounds.low, bounds.high, (args.count, 4))
    for name in pool:
        trained = pool[name].taus
        columns = [bounds.names.index(n) for n in pool[name].box.names]
        if any(np.allclose(tau[columns], t) for tau in taus for t in trained):
            raise SystemExit(f"a benchmark tau is a training task of {name!r}: choose another --seed")
    builders = trees(pool_dir)
    runs = {name: [] for name in builders}
    with tqdm(total=len(taus) * len(builders), unit="episode", disable=args.json) as bar:
        for tau in taus:
            for name, build in builders.items():
                runs[name].append({"tau": tau.round(4).tolist(), **episode(build, tau, args.robot)})
                bar.update()
    report = {
        "benchmark": "learned",
        "robot": args.robot,
        "pool": str(pool_dir),
        "count": args.count,
        "seed": args.seed,
        "trees": {},
    }
    for name, episodes in runs.items():
        errors = [e["placement_error_m"] for e in episodes]
        rate = float(np.mean([e["success"] for e in episodes]))
        report["trees"][name] = {
            "success_rate": rate,
            "mean_placement_error_m": float(np.mean(errors)) if errors else None,
            "mean_episode_s": mean(episodes, "episode_s"),
            "mean_path_length_m": mean(episodes, "path_length"),
            "mean_peak_jerk": mean(episodes, "peak_jerk"),
            "mean_path_length_to_placement_m": mean(episodes, "path_length_to_placement"),
            "mean_peak_jerk_to_placement": mean(episodes, "peak_jerk_to_placement"),
            "mean_wall_s": mean(episodes, "wall_s"),
            "target_success_rate": TARGETS.get(name),
            "met": None
            if name not in TARGETS
            else bool(rate >= TARGETS[name] and errors and np.mean(errors) < MAX_ERROR),
            "failures": [e for e in episodes if not e["success"]],
        }
    if args.json:
        print(json.dumps(report, indent=2))
        return
    print(f"{args.count} tau (seed {args.seed}), pool {pool_dir}")
    print(
        f"{'tree':<10} {'success':>8} {'error cm':>9} {'episode s':>10} {'path m':>13} {'peak jerk':>13} "
        f"{'wall s':>7}  target"
    )
    print(f"{'':<40} {'placed/whole':>13} {'placed/whole':>13}")
    for name, row in report["trees"].items():
        error = row["mean_placement_error_m"]
        target = (
            ""
            if row["met"] is None
            else f">= {row['target_success_rate']:.0%}: {'met' if row['met'] else 'NOT met'}"
        )
        print(
            f"{name:<10} {row['success_rate']:>8.0%} {'-' if error is None else f'{100 * error:.2f}':>9} "
            f"{row['mean_episode_s']:>10.2f} "
            f"{row['mean_path_length_to_placement_m']:>6.2f}/{row['mean_path_length_m']:<6.2f} "
            f"{row['mean_peak_jerk_to_placement']:>6.1f}/{row['mean_peak_jerk']:<6.1f} "
            f"{row['mean_wall_s']:>7.2f}  {target}"
        )
        for failure in row["failures"]:
            print(f"    failed at {failure['tau']}: {failure['message']}")


if __name__ == "__main__":
    main()
