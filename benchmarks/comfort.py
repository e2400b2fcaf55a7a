"""Comfort: are the learned motions as smooth and as quick as the planned ones? Peak jerk of the reach and
the carry and the cycle time of the learned tree against the scripted one, beside the people's own
durations in the recordings the motions were learned from.

    python benchmarks/comfort.py [--json] [--robots aila ur5e] [--count 30] [--seed 2054] [--workers 2]
                                 [--perturb perception] [--out docs/results/comfort.json]

Per robot, ``count`` held-out pick-and-place taus (drawn as ``benchmarks/learned.py`` draws them, as
``benchmarks/learned_tree.py`` does: positions and yaws over the task's box, sizes no training task had,
boxes and cylinders in turn), each run by two trees with the same seed (a child of ``--seed``: mass,
friction and, with ``--perturb``, the perturbations): the **learned** tree that ``besman learn`` wrote
(``examples/pools/pick_place_<robot>/tree.yaml``, run as it is) and the **scripted** tree with nothing
learned (``examples/trees/grasp_then_place.yaml``, the one ``benchmarks/refinement_gain.py`` compares
with). Unperturbed by default.

Measured per run, from the executor's command log (one commanded joint state per control cycle) and the
motion that is running at each tick of the tree (``runner.executor.motion``; a motion's cycles are the
log's rows from its start to the cycle that decided it):

- **Peak jerk** (m/s^3) of the tool centre point along the commanded joints, by
  :func:`besman.sim.block_simulation.hand_measures` (the measure the block refinement and
  ``benchmarks/learned.py`` use: forward kinematics every 5 cycles, 100 Hz, third differences), of the
  first attempt's ``reach`` and of its ``carry`` motion, each over every hand position whose difference
  involves one of its cycles (3 positions beyond either end: a start from rest and a stop show), and over
  everything commanded up to the placement. Each motion's peak also split: at its ``start`` (its first
  10 % of cycles and the positions before), ``interior`` and ``stop`` (its last 10 % and the positions
  after), and the part of which motion holds the peak to the placement (``peak_to_placement_in``). For
  a primitive, how far its joint reference is from rest where it starts (acceleration) and where it ends
  (velocity, acceleration), as shares of the joints' limits.
- **Peak joint jerk** as a share of the joint's jerk limit (largest over the joints; commanded
  accelerations differenced per cycle).
- **Durations** (simulated s): the reach and carry motions; grasp to release (from the end of the hand's
  closing on the object to the end of the opening that let it go); the **cycle time**, from the start of
  the run to the moment the object is placed: the end of the ``release`` motion (the gripper open, the
  object standing on the shelf) that completed the placement (the last release of a run that succeeded;
  the retreat and the return home after it are not counted). Cycle times (and the other durations and
  the peak jerk to the placement) are compared only on the tasks where both trees succeeded ("at equal
  success"); the reach's and the carry's peak jerk on every task where both trees ran the motion.

Reported per robot and tree: median and 90th percentile of each measure, successes; and the paired ratios
learned / scripted (ratio of the means over the paired tasks, with the 95 % bootstrap interval over the
tasks of ``refinement_gain.bootstrap``, and the median of the per-task ratios). The issue's bars (54, item
2): peak jerk ratio <= 1 for the reach and for the carry, cycle time ratio <= 1; each MET or NOT MET (on
the ratio of the means). Beside them the people's own durations in the manually segmented recordings
(``../shared/data/dfki_pick_and_place``; ``examples/data``'s two when that is absent, said in the JSON):
the second pick and place of each run, the one the pools learn from (reach ``approach_right``, carry
``move_obj_shelf``, grasp to release from the reach's end to the start of ``move_to_rest_down``, pick to
place from the reach's start to there), median and range over the recordings.

JSON to ``--out`` always (and stdout with ``--json``), the figure beside it (``.png``); a short table.
"""

from __future__ import annotations

import argparse
import json
import multiprocessing
import sys
import time
from concurrent.futures import ProcessPoolExecutor
from pathlib import Path

import numpy as np
from learned import held_out, training_taus
from refinement_gain import SCRIPTED, bootstrap

from besman.core.seeds import child_seed
from besman.sim.block_simulation import PATH_STRIDE
from besman.skills import SkillTemplatePool
from besman.tasks import task

ROOT = Path(__file__).resolve().parent.parent
RECORDINGS = ROOT.parent / "shared" / "data" / "dfki_pick_and_place"
FALLBACK = ROOT / "examples" / "data"
TREES = ("learned", "scripted")
EPISODES, BOOTSTRAP = 2, 3  # children of --seed: the runs' seeds, the bootstrap's draws
EDGE = 0.1  # share of a motion's cycles at either end left out of its interior peak
MARGIN = 3 * PATH_STRIDE  # cycles beyond a motion's ends whose hand positions measure its jerk with it
BAR = 1.0  # learned / scripted, for the reach's and the carry's peak jerk and for the cycle time
JERK = ("reach_peak_jerk", "carry_peak_jerk", "peak_jerk_to_placement")
MEASURES = (
    *JERK,
    "reach_interior_peak_jerk",
    "reach_start_peak_jerk",
    "reach_stop_peak_jerk",
    "carry_interior_peak_jerk",
    "carry_start_peak_jerk",
    "carry_stop_peak_jerk",
    "reach_joint_jerk_share",
    "carry_joint_jerk_share",
    "reach_s",
    "carry_s",
    "grasp_to_release_s",
    "cycle_s",
)
BARS = {"reach_peak_jerk": BAR, "carry_peak_jerk": BAR, "cycle_s": BAR}
# The people's second pick and place (the one the pools learn from): reach, carry, and where they let go.
HUMAN = {"reach": "approach_right", "carry": "move_obj_shelf", "after": "move_to_rest_down"}


# -- one run -------------------------------------------------------------------------------------------------


def episode(arguments: tuple) -> dict:
    """One run of a tree on a task: success and the measures of the module documentation."""
    from besman.sim.block_simulation import hand_measures
    from besman.tasks.episodes import MotionTrail
    from besman.tasks.running import run

    tree, robot, tau, seed, perturb = arguments
    trail = MotionTrail()
    found: dict = {}

    def observe(runner, record) -> None:
        found.setdefault("runner", runner)
        found.setdefault("start", record["time"])
        trail(runner, record)

    summary = run(
        "pick-place",
        tree,
        robot=robot,
        values=task("pick-place").split(tau),
        seed=seed,
        perturb=perturb,
        observe=observe,
    )
    executor = found["runner"].executor
    log, arm, period = executor.log, executor.arm, executor.config.control_period
    spans = [
        (m, first, first + (m.ended if m.status.value != "running" else m.cycles))
        for m, first in trail.started
    ]
    names = [m.name for m, _, _ in spans]
    result = {
        "success": bool(summary.success),
        "first_attempt": bool(summary.success and names.count("reach") == 1 and names.count("carry") == 1),
        "message": summary.message,
        "motions": [
            [m.name, round(float(log.times[a] - period), 3), round((b - a) * period, 3)] for m, a, b in spans
        ],
    }

    def jerk(a: int, b: int) -> float:
        return hand_measures(arm, log.positions[max(a, 0) : max(b, 0)], period)["peak_jerk"]

    def parts(a: int, b: int) -> dict[str, float]:
        """A motion's peak jerk (every hand position that involves one of its cycles: MARGIN beyond
        either end), at its start, inside and at its stop."""
        edge = int(EDGE * (b - a))
        return {
            "peak_jerk": jerk(a - MARGIN, b + MARGIN),
            "start_peak_jerk": jerk(a - MARGIN, a + edge),
            "interior_peak_jerk": jerk(a + edge, b - edge),
            "stop_peak_jerk": jerk(b - edge, b + MARGIN),
        }

    for block in ("reach", "carry"):
        motion = next(((m, a, b) for m, a, b in spans if m.name == block), None)
        if motion is None:
            keys = ("peak_jerk", "interior_peak_jerk", "start_peak_jerk", "stop_peak_jerk", "s")
            result.update({f"{block}_{key}": None for key in keys})
            result[f"{block}_joint_jerk_share"] = None
            continue
        m, a, b = motion
        result.update({f"{block}_{key}": value for key, value in parts(a, b).items()})
        result[f"{block}_joint_jerk_share"] = float(
            (np.abs(np.diff(log.accelerations[a:b], axis=0)).max(axis=0) / period / arm.max_jerk).max()
        )
        result[f"{block}_s"] = (b - a) * period
        reference = getattr(m, "reference", None)
        if reference is not None and reference.velocities is not None:  # how far from rest it starts and ends
            result[f"{block}_reference"] = {
                "s": round(float(reference.times[-1] - reference.times[0]), 3),
                "start_acceleration_share": float(
                    (np.abs(reference.accelerations[0]) / arm.max_acceleration).max()
                ),
                "end_velocity_share": float((np.abs(reference.velocities[-1]) / arm.max_velocity).max()),
                "end_acceleration_share": float(
                    (np.abs(reference.accelerations[-1]) / arm.max_acceleration).max()
                ),
            }
    releases = [
        k for k, (m, _, _) in enumerate(spans) if m.name == "release" and m.status.value == "succeeded"
    ]
    if not summary.success or not releases:
        result.update(peak_jerk_to_placement=None, grasp_to_release_s=None, cycle_s=None, peak_motion=None)
        return result
    placed = releases[-1]
    end = spans[placed][2]
    closes = [k for k in range(placed) if spans[k][0].name == "close"]
    grasped = float(log.times[spans[closes[-1]][2] - 1]) if closes else found["start"]
    result["cycle_s"] = float(log.times[end - 1] - found["start"])
    result["grasp_to_release_s"] = float(log.times[end - 1] - grasped)
    result["peak_jerk_to_placement"] = jerk(0, end)
    where = {
        f"{m.name} ({part.split('_')[0]})": value
        for m, a, b in spans[: placed + 1]
        if m.name not in ("open", "close", "release")  # the arm holds still while the gripper moves
        for part, value in parts(a, b).items()
        if part != "peak_jerk"
    }
    result["peak_motion"] = max(where, key=where.get)
    return result


# -- the people's durations ----------------------------------------------------------------------------------


def human_durations() -> dict:
    """The people's reach, carry, grasp-to-release and pick-to-place durations (s) in the manually
    segmented recordings, per recording and summarised."""
    from besman.learning import load

    folder, fallback = (RECORDINGS, False) if RECORDINGS.is_dir() else (FALLBACK, True)
    rows = []
    for path in sorted(folder.glob("*.tsv")):
        demo = load(path)
        segments = {s.label: s for s in demo.segments}
        if not all(label in segments for label in HUMAN.values()):
            continue

        def at(frame: int, demo=demo) -> float:
            return float(np.interp(frame, demo.frames, demo.times))

        reach, carry, after = (segments[HUMAN[k]] for k in ("reach", "carry", "after"))
        rows.append(
            {
                "recording": path.name,
                "reach_s": at(reach.end_frame) - at(reach.start_frame),
                "carry_s": at(carry.end_frame) - at(carry.start_frame),
                "grasp_to_release_s": at(after.start_frame) - at(reach.end_frame),
                "pick_to_place_s": at(after.start_frame) - at(reach.start_frame),
            }
        )
    keys = ("reach_s", "carry_s", "grasp_to_release_s", "pick_to_place_s")
    return {
        "source": str(folder.relative_to(ROOT.parent) if folder.is_relative_to(ROOT.parent) else folder),
        "fallback_to_examples": fallback,
        "segments": HUMAN,
        "recordings": len(rows),
        **{
            key: {
                "median": float(np.median([r[key] for r in rows])),
                "min": float(min(r[key] for r in rows)),
                "max": float(max(r[key] for r in rows)),
            }
            for key in keys
        },
        "per_recording": rows,
    }


# -- the report ----------------------------------------------------------------------------------------------


def mean_ratio(learned: np.ndarray, scripted: np.ndarray) -> float:
    return learned.mean() / scripted.mean()


def spread(values: list) -> dict | None:
    values = [v for v in values if v is not None]
    if not values:
        return None
    return {"median": float(np.median(values)), "p90": float(np.percentile(values, 90)), "n": len(values)}


def motion_durations(runs: list[dict]) -> dict:
    """The median duration (s) of each motion of the runs that succeeded, in the order they ran (each
    name's first run): where a cycle's time goes."""
    durations: dict[str, list[float]] = {}
    for run in runs:
        if not run["success"]:
            continue
        first: dict[str, float] = {}
        for name, _, seconds in run["motions"]:
            first.setdefault(name, seconds)
        for name, seconds in first.items():
            durations.setdefault(name, []).append(seconds)
    return {name: round(float(np.median(values)), 3) for name, values in durations.items()}


def measure(robot: str, args: argparse.Namespace) -> dict:
    started = time.time()
    pool = ROOT / "examples" / "pools" / f"pick_place_{robot}"
    trees = {"learned": pool / "tree.yaml", "scripted": SCRIPTED}
    taus, sizes = held_out(robot, training_taus(SkillTemplatePool(pool)), args.count, args.seed)
    seeds = [child_seed(args.seed, EPISODES, k) % 2**31 for k in range(args.count)]
    jobs = [
        (str(trees[name]), robot, tau, seeds[k], args.perturb) for name in TREES for k, tau in enumerate(taus)
    ]
    if args.workers == 1:
        results = [episode(job) for job in jobs]
    else:
        context = multiprocessing.get_context("spawn")
        with ProcessPoolExecutor(args.workers, mp_context=context) as executor:
            results = list(executor.map(episode, jobs, chunksize=2))
    n = args.count
    runs = {name: results[i * n : (i + 1) * n] for i, name in enumerate(TREES)}
    report: dict = {"sizes": sizes, "trees": {}}
    for name in TREES:
        found = runs[name]
        peaks: dict[str, int] = {}
        for r in found:
            if r["peak_motion"] is not None:
                peaks[r["peak_motion"]] = peaks.get(r["peak_motion"], 0) + 1
        report["trees"][name] = {
            "tree": str(trees[name].relative_to(ROOT)),
            "success": sum(r["success"] for r in found),
            "first_attempt": sum(r["first_attempt"] for r in found),
            "runs": n,
            **{key: spread([r[key] for r in found]) for key in MEASURES},
            "peak_to_placement_in": dict(sorted(peaks.items(), key=lambda item: -item[1])),
            "motion_s": motion_durations(found),
            "failures": [
                {"tau": taus[k].round(4).tolist(), "message": r["message"]}
                for k, r in enumerate(found)
                if not r["success"]
            ],
        }
        if name == "learned":
            report["trees"][name]["reference_ends"] = {
                block: {
                    key: spread([r.get(f"{block}_reference", {}).get(key) for r in found])
                    for key in ("start_acceleration_share", "end_velocity_share", "end_acceleration_share")
                }
                for block in ("reach", "carry")
            }
    ratios = {}
    for key in (*JERK, "reach_s", "carry_s", "grasp_to_release_s", "cycle_s"):
        pairs = [
            (a[key], b[key])
            for a, b in zip(runs["learned"], runs["scripted"], strict=True)
            if a[key] is not None and b[key] is not None and a["success"] and b["success"]
        ]
        if key in ("reach_peak_jerk", "carry_peak_jerk"):  # the first attempt's motions, whatever came after
            pairs = [
                (a[key], b[key])
                for a, b in zip(runs["learned"], runs["scripted"], strict=True)
                if a[key] is not None and b[key] is not None
            ]
        if not pairs:
            ratios[key] = None
            continue
        learned, scripted = (np.array(column, dtype=float) for column in zip(*pairs, strict=True))
        value = float(mean_ratio(learned, scripted))
        ratios[key] = {
            "ratio": value,
            "interval": bootstrap(mean_ratio, (learned, scripted), child_seed(args.seed, BOOTSTRAP))
            if len(pairs) > 1
            else [value, value],
            "median_of_ratios": float(np.median(learned / scripted)),
            "pairs": len(pairs),
        }
        if key in BARS:
            ratios[key]["bar"] = BARS[key]
            ratios[key]["met"] = value <= BARS[key]
    report["ratios"] = ratios
    report["minutes"] = round((time.time() - started) / 60, 1)
    return report


def plot(results: dict, path: Path) -> None:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    robots = list(results["robots"])
    keys = ("reach_peak_jerk", "carry_peak_jerk", "peak_jerk_to_placement", "cycle_s")
    labels = (
        "reach\npeak jerk",
        "carry\npeak jerk",
        "peak jerk\nto placement",
        "cycle time\n(both succeeded)",
    )
    figure, (ratio_axis, time_axis) = plt.subplots(1, 2, figsize=(11, 4))
    for r, robot in enumerate(robots):
        ratios = results["robots"][robot]["ratios"]
        for k, key in enumerate(keys):
            entry = ratios.get(key)
            if entry is None:
                continue
            x = k + 0.2 * (r - (len(robots) - 1) / 2)
            low, high = entry["interval"]
            ratio_axis.errorbar(
                x,
                entry["ratio"],
                [[entry["ratio"] - low], [high - entry["ratio"]]],
                fmt="o",
                color=f"C{r}",
                label=robot if k == 0 else None,
            )
    ratio_axis.axhline(BAR, color="k", linestyle="--", linewidth=0.8, label="bar: learned <= scripted")
    ratio_axis.set_xticks(range(len(keys)), labels, fontsize=8)
    ratio_axis.set_ylabel("learned / scripted (mean ratio, 95 % CI)")
    ratio_axis.legend(fontsize=8)
    # Durations: each robot's two trees (median, 10th-90th percentile) and the people (median, range).
    rows = [("reach_s", "reach"), ("carry_s", "carry"), ("cycle_s", "start to placed")]
    human = results["human"]
    human_keys = {"reach_s": "reach_s", "carry_s": "carry_s", "cycle_s": "pick_to_place_s"}
    series = [(f"{robot} {tree}", robot, tree) for robot in robots for tree in TREES] + [
        ("people", None, None)
    ]
    width = 0.8 / len(series)
    for s, (label, robot, tree) in enumerate(series):
        for k, (key, _) in enumerate(rows):
            x = k + (s - (len(series) - 1) / 2) * width
            if robot is None:
                entry = human[human_keys[key]]
                low, high = entry["min"], entry["max"]
            else:
                entry = results["robots"][robot]["trees"][tree][key]
                if entry is None:
                    continue
                low = high = None
            middle = entry["median"]
            color = "grey" if robot is None else f"C{robots.index(robot)}"
            time_axis.bar(
                x,
                middle,
                width,
                color=color,
                alpha=1.0 if tree != "scripted" else 0.45,
                label=label if k == 0 else None,
            )
            if low is not None:
                time_axis.errorbar(x, middle, [[middle - low], [high - middle]], color="k", linewidth=0.8)
    time_axis.set_xticks(range(len(rows)), [label for _, label in rows])
    time_axis.set_ylabel("duration (s, median; people: range)")
    time_axis.legend(fontsize=7)
    perturb = results["perturb"] or "unperturbed"
    figure.suptitle(f"Comfort: {results['count']} held-out pick-and-place tasks per robot ({perturb})")
    figure.tight_layout()
    figure.savefig(path, dpi=120)
    plt.close(figure)


def print_table(results: dict) -> None:
    human = results["human"]
    for robot, found in results["robots"].items():
        trees = found["trees"]
        print(
            f"{robot}: success learned {trees['learned']['success']}/{results['count']}, "
            f"scripted {trees['scripted']['success']}/{results['count']} ({found['minutes']} min)"
        )
        print(
            f"  {'measure':<24} {'learned med/p90':>16} {'scripted med/p90':>17} {'ratio [95 % CI]':>24}  bar"
        )
        parts = [f"{b}_{p}_peak_jerk" for b in ("reach", "carry") for p in ("start", "interior", "stop")]
        for key in (*JERK, *parts, "reach_s", "carry_s", "grasp_to_release_s", "cycle_s"):
            cells = []
            for tree in TREES:
                entry = trees[tree][key]
                cells.append("-" if entry is None else f"{entry['median']:.2f}/{entry['p90']:.2f}")
            ratio = found["ratios"].get(key)
            text = (
                "-"
                if ratio is None
                else f"{ratio['ratio']:.2f} [{ratio['interval'][0]:.2f}, {ratio['interval'][1]:.2f}]"
            )
            bar = "" if ratio is None or "met" not in ratio else ("MET" if ratio["met"] else "NOT MET")
            print(f"  {key:<24} {cells[0]:>16} {cells[1]:>17} {text:>24}  {bar}")
        print(f"  learned peak to placement in: {trees['learned']['peak_to_placement_in']}")
    print(
        f"people ({human['recordings']} recordings, {human['source']}): "
        + ", ".join(
            f"{key} {human[key]['median']:.2f} s [{human[key]['min']:.2f}, {human[key]['max']:.2f}]"
            for key in ("reach_s", "carry_s", "grasp_to_release_s", "pick_to_place_s")
        )
    )


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--json", action="store_true", help="print the results as JSON")
    parser.add_argument("--robots", nargs="+", default=["aila", "ur5e"])
    parser.add_argument("--count", type=int, default=30, help="held-out tasks per robot")
    parser.add_argument("--seed", type=int, default=2054, help="draws the tasks and the runs' seeds")
    parser.add_argument("--workers", type=int, default=2)
    parser.add_argument("--perturb", choices=["perception"], default=None, help="perception errors")
    parser.add_argument("--out", type=Path, default=ROOT / "docs" / "results" / "comfort.json")
    args = parser.parse_args(argv)
    if args.count < 1 or args.workers < 1:
        parser.error("--count and --workers must be at least 1")
    results = {
        "count": args.count,
        "seed": args.seed,
        "perturb": args.perturb,
        "bars": {key: f"learned / scripted <= {value}" for key, value in BARS.items()},
        "human": human_durations(),
        "robots": {robot: measure(robot, args) for robot in args.robots},
    }
    args.out.parent.mkdir(parents=True, exist_ok=True)
    args.out.write_text(json.dumps(results, indent=1) + "\n")
    plot(results, args.out.with_suffix(".png"))
    if args.json:
        print(json.dumps(results, indent=1))
    else:
        print_table(results)
    return 0


if __name__ == "__main__":
    sys.exit(main())
