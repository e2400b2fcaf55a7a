"""Grasp-then-place learned from people against planned by inverse kinematics and against a ProMP baseline.

    python benchmarks/learned.py [--json] [--robot aila] [--pool POOL] [--count 100] [--seed 2026]
                                 [--refined] [--workers 2]

Held-out tasks: ``count`` pick-and-place taus on the robot (the pool: ``examples/pools/pick_place_<robot>``
unless given), drawn with ``seed``: the object's and the place's positions and yaws uniformly over the task's
box (any object yaw, any place yaw); :data:`SIZES` object sizes drawn from the task's size box with a child
seed, each checked to be no training task's size (:data:`SIZE_GAP`), taken in turn (20 taus each of 100);
the shape alternating box, cylinder (a cylinder's depth is its width). The script checks that no held-out
tau is a training task of the pool (its templates' provenance). Each episode's seed (a child of ``seed``)
draws the object's mass and friction, the same for every tree. The report lists, per block, the training
tasks whose move the planner now plans otherwise than when the pool was learned (a pool older than the
planner; the templates and the baseline both meet the moves of today's planner).

Trees, each on every tau, on the task ``pick-place`` in MuJoCo (independent runs on ``workers`` processes):

- ``ik``: ``examples/trees/grasp_then_place.yaml``, every motion planned (point-to-point reach and carry);
- ``zero-shot``: ``examples/trees/grasp_then_place_learned.yaml`` with the templates' means only (online
  refinement off);
- ``promp``: the same learned tree whose pool holds, per block, ProMP conditioning on the move's start and
  end configurations (:class:`besman.tasks.pick_place.promp_baseline.ProMPBaseline`), learned from the same
  training tasks; its weights per joint chosen per block by leave-one-out on the training trajectories
  (reported);
- ``refined`` (with ``--refined``; slow): the learned tree refining every template instance online first
  (at most 25 rollouts each in a copy of the world), whatever the template's uncertainty.

Per tree: success rate (the tree succeeded and the task's rule holds: after settling the object stands
upright on the shelf within 2 cm of the target and 5 deg of its yaw), how many runs succeed within
:data:`PRECISE` (1 cm and 5 deg), mean and max placement error (cm) and yaw error (deg), episode time
(simulated), the hand's path length and peak jerk (from the commanded joints,
:func:`besman.sim.block_simulation.hand_measures`) and the wall time per episode. The learned trees also
return the arm home, which the IK-planned tree does not, so path and jerk are given up to the placement (the
commands before the return home) and over the whole episode. Targets (:data:`TARGETS`): the share of runs that
succeed within :data:`PRECISE` is >= 98 % for ``ik`` and >= 95 % for ``zero-shot``. The text table gives
the counts as ratios (k/n) and each tree's time, path and jerk as a ratio to the ``ik`` tree's; the
failures follow with their tau and message.
"""

from __future__ import annotations

import argparse
import json
import multiprocessing
import re
import sys
from concurrent.futures import ProcessPoolExecutor, as_completed
from pathlib import Path

import numpy as np
from tqdm import tqdm

from besman.core.seeds import child_seed
from besman.skills import SkillTemplatePool
from besman.tasks import task

ROOT = Path(__file__).resolve().parent.parent
TREES = ROOT / "examples" / "trees"
LEARNED = "grasp_then_place_learned.yaml"
TARGETS = {"ik": 0.98, "zero-shot": 0.95}  # shares of runs that succeed within PRECISE
PRECISE = (0.01, 5.0)  # m and deg
SIZES = 5  # object sizes never trained on, taken in turn
SIZE_GAP = 0.002  # m: a drawn size this close to a training size in every dimension is drawn again
POSITIONS, SIZE_DRAWS, EPISODES = 0, 1, 2  # the child seeds of --seed for each random stream
PROMP_POOL = "learned_benchmark:PROMP"  # the reference the promp tree's file names, registered per worker
RETURN = "/return home"  # the learned tree's last subtree: what the IK-planned tree has no counterpart of
THRESHOLD = re.compile(r"refine_above: [0-9.e+-]+")
THRESHOLD_LINE = re.compile(r"^\s*refine_above: .*\n", re.MULTILINE)
POOL_VALUE = re.compile(r"pool: \S+")


def training_taus(pool: SkillTemplatePool) -> np.ndarray:
    """Every training task (whole pick-and-place tau) of the pool's templates."""
    taus = []
    for name in pool:
        training = pool[name].provenance.get("training") or []
        if not training or any("task_tau" not in entry for entry in training):
            raise SystemExit(
                f"template {name!r} of {pool.directory} names no training task_tau: a pool learned on the "
                "task's whole tau (besman learn) is needed"
            )
        taus += [entry["task_tau"] for entry in training]
    return np.array(taus, dtype=float)


def effective_size(size: np.ndarray, shape: float) -> np.ndarray:
    """The size an object is made with: a cylinder's depth is its width."""
    return np.array([size[0], size[0], size[2]]) if shape == 1 else np.asarray(size, float)


def held_out(robot: str, trained: np.ndarray, count: int, seed: int) -> tuple[np.ndarray, list[dict]]:
    """``count`` held-out taus (see the module documentation) and the sizes they use, each with its
    distance from the nearest training size (max over width, depth, height)."""
    bounds = task("pick-place").bounds(robot)
    low, high = np.asarray(bounds.low), np.asarray(bounds.high)
    columns = {name: bounds.names.index(name) for name in bounds.names}
    place = [columns[n] for n in ("object_x", "object_y", "object_yaw", "place_x", "place_y", "place_yaw")]
    size = [columns[n] for n in ("object_width", "object_depth", "object_height")]
    shape = columns["shape"]
    taus = np.empty((count, len(bounds.names)))
    taus[:, place] = np.random.default_rng(child_seed(seed, POSITIONS)).uniform(
        low[place], high[place], (count, len(place))
    )
    trained_sizes = np.array([effective_size(t[size], t[shape]) for t in trained])
    rng = np.random.default_rng(child_seed(seed, SIZE_DRAWS))
    sizes: list[np.ndarray] = []
    while len(sizes) < SIZES:
        drawn = rng.uniform(low[size], high[size])
        variants = [effective_size(drawn, s) for s in (0, 1)]
        if all(np.abs(trained_sizes - v).max(axis=1).min() > SIZE_GAP for v in variants):
            sizes.append(drawn)
    for index in range(count):
        taus[index, shape] = index % 2
        taus[index, size] = effective_size(sizes[index % SIZES], index % 2)
    for tau in taus:
        if np.any(np.all(np.isclose(trained, tau), axis=1)):
            raise SystemExit(
                f"held-out tau {tau.round(4).tolist()} is a training task: choose another --seed"
            )
    described = [
        {
            "size_m": drawn.round(4).tolist(),
            "nearest_training_size_m": float(
                min(np.abs(trained_sizes - effective_size(drawn, s)).max(axis=1).min() for s in (0, 1))
            ),
        }
        for drawn in sizes
    ]
    return taus, described


# -- the worker processes ------------------------------------------------------------------------------------

_WORKER: dict = {}


def _start_worker(pool_dir: str, robot: str, moves: dict, refined: bool) -> None:
    """A worker's state: the pool, its blocks' training moves (for the ProMP baseline) and the tree files'
    texts per tree."""
    text = (TREES / LEARNED).read_text()
    if not THRESHOLD.search(text) or not POOL_VALUE.search(text):
        raise SystemExit(f"{LEARNED} sets no refine_above or no pool; update the benchmark")
    sources = {
        "zero-shot": THRESHOLD.sub("refine_above: 1.0e9", text),
        "promp": POOL_VALUE.sub(f"pool: {PROMP_POOL}", THRESHOLD_LINE.sub("", text)),
    }
    if refined:
        sources["refined"] = THRESHOLD.sub("refine_above: 0.0", text)
    _WORKER.update(pool=Path(pool_dir), robot=robot, moves=moves, sources=sources, weights=None)


def _select(block: str) -> dict:
    """The leave-one-out selection of the ProMP's weights for ``block``."""
    from besman.tasks.pick_place.promp_baseline import select_weights

    return select_weights(_WORKER["moves"][block], SkillTemplatePool(_WORKER["pool"])[block].prototype)


def _tree(name: str, weights: dict):
    from besman.trees import load_tree
    from besman.trees.files import loads_tree

    if name == "ik":
        return load_tree(TREES / "grasp_then_place.yaml")
    if name == "promp":
        if _WORKER["weights"] != weights:  # built once per worker
            from besman.tasks.pick_place.promp_baseline import baseline_pool
            from besman.trees.registry import register_pool

            register_pool(PROMP_POOL, baseline_pool(_WORKER["pool"], _WORKER["moves"], weights))
            _WORKER["weights"] = weights
        return loads_tree(_WORKER["sources"][name], base=TREES, source=LEARNED)
    return loads_tree(_WORKER["sources"][name], base=TREES, source=LEARNED, pool=_WORKER["pool"])


def _episode(name: str, tau: list[float], seed: int, weights: dict) -> dict:
    from besman.sim.block_simulation import hand_measures
    from besman.tasks.running import prepare

    values = task("pick-place").split(np.asarray(tau))
    prepared = prepare("pick-place", _tree(name, weights), values=values, robot=_WORKER["robot"], seed=seed)
    runner = prepared.runner
    outcome = prepared.judge(runner.run())
    executor = runner.executor
    log, period = executor.log, executor.config.control_period
    placed = log.times <= placing_end(runner)
    error, yaw_error = (outcome.measurements[k] for k in ("placement_error_m", "placement_yaw_error_deg"))
    return {
        "tau": [round(v, 4) for v in tau],
        "seed": seed,
        "success": outcome.success,
        "precise": bool(outcome.success and error <= PRECISE[0] and yaw_error <= PRECISE[1]),
        "placement_error_m": error,
        "placement_yaw_error_deg": yaw_error,
        "episode_s": outcome.sim_time_s,
        "wall_s": outcome.wall_time_s,
        "message": outcome.message,
        "outcome": outcome.outcome,
        **hand_measures(executor.arm, log.positions, period),
        **{
            f"{key}_to_placement": value
            for key, value in hand_measures(executor.arm, log.positions[placed], period).items()
        },
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


# -- the report ----------------------------------------------------------------------------------------------


def summary(name: str, episodes: list[dict]) -> dict:
    def values(key: str) -> np.ndarray:
        return np.array([e[key] for e in episodes], dtype=float)

    errors, yaws = values("placement_error_m"), values("placement_yaw_error_deg")
    precise = int(sum(e["precise"] for e in episodes))
    row = {
        "runs": len(episodes),
        "successes": int(sum(e["success"] for e in episodes)),
        "success_rate": float(np.mean(values("success"))),
        "precise": precise,
        "precise_rate": precise / len(episodes),
        "within_1cm": int(np.sum(errors <= PRECISE[0])),
        "within_5deg": int(np.sum(yaws <= PRECISE[1])),
        "mean_placement_error_m": float(errors.mean()),
        "max_placement_error_m": float(errors.max()),
        "mean_yaw_error_deg": float(yaws.mean()),
        "max_yaw_error_deg": float(yaws.max()),
        "mean_episode_s": float(values("episode_s").mean()),
        "mean_path_length_m": float(values("path_length").mean()),
        "mean_peak_jerk": float(values("peak_jerk").mean()),
        "mean_path_length_to_placement_m": float(values("path_length_to_placement").mean()),
        "mean_peak_jerk_to_placement": float(values("peak_jerk_to_placement").mean()),
        "mean_wall_s": float(values("wall_s").mean()),
        "target_precise_rate": TARGETS.get(name),
        "met": None if name not in TARGETS else precise / len(episodes) >= TARGETS[name],
        "failures": [e for e in episodes if not e["success"]],
    }
    return row


def relative(row: dict, ik: dict | None, key: str) -> str:
    """A tree's mean and its ratio to the IK-planned tree's."""
    return f"{row[key]:.2f} ({row[key] / ik[key]:.2f})" if ik and ik[key] else f"{row[key]:.2f}"


def print_table(report: dict) -> None:
    print(
        f"{report['count']} held-out tau (seed {report['seed']}) on {report['robot']}, "
        f"pool {report['pool']}; sizes {', '.join(str(s['size_m']) for s in report['sizes'])}"
    )
    for block, tasks in report["changed_training_moves"].items():
        if tasks:
            print(
                f"warning: the planner now moves {block} otherwise than the pool learned in training tasks "
                f"{tasks} (the pool predates the planner)"
            )
    for block, selection in report["promp_selection"].items():
        scores = ", ".join(
            f"{w}: {1000 * r:.1f} mrad, {selection['peak_acceleration_share_of_limit'][w]:.2f} x"
            for w, r in selection["rmse_rad"].items()
        )
        print(
            f"promp {block}: {selection['weights_per_joint']} weights per joint (leave-one-out RMSE and peak "
            f"joint acceleration as a share of its limit, by weights: {scores})"
        )
    ik = report["trees"].get("ik")
    header = (
        f"{'tree':<10} {'success':>8} {'<=1cm,5deg':>10} {'err cm':>11} {'yaw deg':>11} {'episode s':>13} "
        f"{'path m to place':>16} {'jerk to place':>14} {'wall s':>7}  target"
    )
    print(header)
    ratio = "(x ik)"
    print(f"{'':<30} {'mean/max':>11} {'mean/max':>11} {ratio:>13} {ratio:>16} {ratio:>14}")
    for name, row in report["trees"].items():
        target = (
            ""
            if row["met"] is None
            else f">= {row['target_precise_rate']:.0%}: {'met' if row['met'] else 'NOT met'}"
        )
        print(
            f"{name:<10} {row['successes']:>4}/{row['runs']:<3} {row['precise']:>6}/{row['runs']:<3} "
            f"{100 * row['mean_placement_error_m']:>5.2f}/{100 * row['max_placement_error_m']:<5.2f} "
            f"{row['mean_yaw_error_deg']:>5.1f}/{row['max_yaw_error_deg']:<5.1f} "
            f"{relative(row, ik, 'mean_episode_s'):>13} "
            f"{relative(row, ik, 'mean_path_length_to_placement_m'):>16} "
            f"{relative(row, ik, 'mean_peak_jerk_to_placement'):>14} {row['mean_wall_s']:>7.2f}  {target}"
        )
    for name, row in report["trees"].items():
        for failure in row["failures"]:
            print(
                f"  {name} failed at {failure['tau']} (seed {failure['seed']}): {failure['message']}; "
                f"{failure['outcome']}"
            )


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--json", action="store_true")
    parser.add_argument("--robot", default="aila", help="the robot (default: aila)")
    parser.add_argument("--pool", default=None, help="the pool (default: the robot's in examples/pools)")
    parser.add_argument("--count", type=int, default=100)
    parser.add_argument("--seed", type=int, default=2026)
    parser.add_argument("--refined", action="store_true", help="also the tree refining online (slow)")
    parser.add_argument("--workers", type=int, default=2, help="worker processes (default: 2)")
    args = parser.parse_args()
    if args.count < 1 or args.workers < 1:
        raise SystemExit(f"--count and --workers must be at least 1, got {args.count} and {args.workers}")
    pool_dir = Path(args.pool) if args.pool else ROOT / "examples" / "pools" / f"pick_place_{args.robot}"
    pool = SkillTemplatePool(pool_dir)
    taus, sizes = held_out(args.robot, training_taus(pool), args.count, args.seed)
    seeds = [child_seed(args.seed, EPISODES, index) for index in range(args.count)]
    names = ["ik", "zero-shot", "promp", *(["refined"] if args.refined else [])]

    from besman.tasks.pick_place.promp_baseline import changed_moves, training_moves

    moves = {block: training_moves(pool[block], args.robot) for block in pool}
    changed = {block: changed_moves(pool[block], moves[block]) for block in pool}
    runs: dict[str, list] = {name: [None] * args.count for name in names}
    # Spawned, not forked: a fork of a process that has run MuJoCo (the training moves) may inherit its locks.
    context = multiprocessing.get_context("spawn")
    initargs = (str(pool_dir), args.robot, moves, args.refined)
    with ProcessPoolExecutor(
        args.workers, mp_context=context, initializer=_start_worker, initargs=initargs
    ) as workers:
        selected = {workers.submit(_select, block): block for block in moves}
        selection = {}
        with tqdm(total=len(selected), desc="ProMP weights", disable=args.json, file=sys.stderr) as bar:
            for job in as_completed(selected):
                selection[selected[job]] = job.result()
                bar.update()
        selection = {block: selection[block] for block in moves}  # in the pool's order
        weights = {block: chosen["weights_per_joint"] for block, chosen in selection.items()}
        jobs = {
            workers.submit(_episode, name, tau.tolist(), seed, weights): (name, index)
            for index, (tau, seed) in enumerate(zip(taus, seeds, strict=True))
            for name in names
        }
        with tqdm(total=len(jobs), unit="episode", disable=args.json, file=sys.stderr) as bar:
            for job in as_completed(jobs):
                name, index = jobs[job]
                runs[name][index] = job.result()
                bar.update()
    report = {
        "benchmark": "learned",
        "robot": args.robot,
        "pool": str(pool_dir),
        "count": args.count,
        "seed": args.seed,
        "sizes": sizes,
        "changed_training_moves": changed,
        "promp_selection": selection,
        "trees": {name: summary(name, episodes) for name, episodes in runs.items()},
    }
    if args.json:
        print(json.dumps(report, indent=2))
    else:
        print_table(report)


if __name__ == "__main__":
    main()
