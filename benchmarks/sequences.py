"""Refining the blocks as one sequence (jointly, each block credited with its cost-to-go) against one block
after the other, at equal budgets of whole-task rollouts, judged by the tree learned from the recordings.

    python benchmarks/sequences.py [--json] [--robots aila ur5e] [--tasks 8] [--budget 48]
                                   [--count 200] [--plain 100] [--seed 2027] [--workers 2]
                                   [--work DIR] [--out docs/results/sequences.json]

Per robot, from the committed pool's retargeted shapes (``examples/pools/pick_place_<robot>/work/shapes``)
and its task structure (``work/structure.json``), the two refinements of ``besman learn --refinement``:

- ``sequence``: per training task, every block's forcing weights and subgoals refined together on
  whole-task rollouts with the task's perturbations, each block's CMA-ES told its cost-to-go;
- ``sequence-by-block``: the same rollouts and budget, the blocks one after the other, each for its own cost;

each with ``tasks`` training tasks and ``budget`` whole-task rollouts per task (the same seeds: the same
training tasks and perturbations per call), stored as a pool in ``--work`` with its learned tree
(``tree.yaml``: the recordings' structure with the refined subgoals). Measured beside them: the committed
pool (``blocks``: each block refined alone from the planned starts, its tree the committed ``tree.yaml``)
and, as the control with no learned parameter at all, the IK-planned tree (``ik``,
``examples/trees/grasp_then_place.yaml``).

Evaluation, every tree on the same tasks: ``count`` held-out taus (drawn as ``benchmarks/learned.py`` draws
them; none a training task of any of the pools), each perturbed (the task's perturbations: perception
errors at every look; the even-numbered half also pushed during the reach), and the first ``plain`` of them
unperturbed; episode k's seed (a child of ``seed``) draws the object's mass and friction and the
perturbations alike for every tree. Reported: task success, first-attempt success (one reach and one
carry: no try failed) and the failures' messages, per robot, refinement and condition; training costs before
and after. JSON to ``--out`` (and stdout with ``--json``), the figure beside it (``.png``).
"""

from __future__ import annotations

import argparse
import json
import multiprocessing
import sys
import time
from collections import Counter
from concurrent.futures import ProcessPoolExecutor
from pathlib import Path

import numpy as np
from learned import held_out, training_taus
from learned_tree import episode

from besman.core.seeds import child_seed
from besman.learning.pipeline.record import LearnSettings
from besman.learning.pipeline.refinement import store_templates
from besman.learning.pipeline.sequence_refinement import refine_sequences, subgoals
from besman.learning.pipeline.task_structure import TaskStructure
from besman.skills import SkillTemplatePool
from besman.tasks import task
from besman.trees.learned import write_learned_tree

ROOT = Path(__file__).resolve().parent.parent
REFINEMENTS = ("sequence", "sequence-by-block")
EPISODES = 2  # the child of --seed that seeds the episodes


def learn_pool(robot: str, refinement: str, settings: LearnSettings, work: Path) -> tuple[Path, dict]:
    """The pool of ``refinement`` on ``robot`` in ``work`` (resumed from its cached training tasks) with its
    learned tree; the refined results per block."""
    committed = ROOT / "examples" / "pools" / f"pick_place_{robot}"
    blocks = task("pick-place").building_blocks(robot)
    shapes = {block: committed / "work" / "shapes" / f"{block}.json" for block in blocks.names}
    out = work / f"{robot}-{refinement}"
    (out / "work").mkdir(parents=True, exist_ok=True)
    refined = refine_sequences(shapes, blocks, settings, out / "work" / "refined", shown=True)
    record = json.loads((committed / "work" / "learn.json").read_text())
    record["settings"] = settings.as_dict(blocks)
    store_templates(out, shapes, refined, blocks, settings, record)
    structure = TaskStructure.from_dict(
        json.loads((committed / "work" / "structure.json").read_text())["structure"]
    )
    write_learned_tree(
        out,
        structure,
        task=blocks.task,
        object=blocks.object,
        target=blocks.target,
        subgoals=subgoals(refined),
    )
    return out, refined


def training_summary(refined: dict) -> dict:
    """Per block: its mean cost and its failures over the training tasks' evaluation rollouts, before and
    after; and the subgoals it ended with."""
    summary = {}
    for block, runs in refined.items():
        summary[block] = {
            "cost_before": float(np.mean([-run["start_reward"] for run in runs])),
            "cost_after": float(np.mean([-run["reward"] for run in runs])),
            "failed_before": int(sum(run["start_outcome"]["failed"] for run in runs)),
            "failed_after": int(sum(run["outcome"]["failed"] for run in runs)),
            "subgoals": [run.get("subgoals", {}) for run in runs],
        }
    return summary


def evaluate(
    trees: dict[str, Path], robot: str, taus: np.ndarray, plain: int, seed: int, workers: int
) -> dict:
    """Every tree on every tau perturbed (even k pushed) and on the first ``plain`` unperturbed."""
    jobs, keys = [], []
    for name, tree in trees.items():
        for k, tau in enumerate(taus):
            jobs.append(
                (str(tree), robot, tau, child_seed(seed, EPISODES, k), "push" if k % 2 == 0 else "perception")
            )
            keys.append((name, "perturbed", k))
        for k, tau in enumerate(taus[:plain]):
            jobs.append((str(tree), robot, tau, child_seed(seed, EPISODES, k), None))
            keys.append((name, "unperturbed", k))
    started = time.time()
    context = multiprocessing.get_context("spawn")
    with ProcessPoolExecutor(workers, mp_context=context) as executor:
        results = list(executor.map(episode, jobs, chunksize=4))
    found: dict = {}
    for (name, condition, k), result in zip(keys, results, strict=True):
        entry = found.setdefault(name, {}).setdefault(
            condition,
            {
                "runs": 0,
                "success": 0,
                "first_attempt": 0,
                "pushed": {"runs": 0, "success": 0, "first_attempt": 0},
                "failures": [],
            },
        )
        for target in [entry] + ([entry["pushed"]] if condition == "perturbed" and k % 2 == 0 else []):
            target["runs"] += 1
            target["success"] += result["success"]
            target["first_attempt"] += result["first_attempt"]
        if not result["success"]:
            entry["failures"].append({"k": k, "tau": taus[k].round(4).tolist(), "message": result["message"]})
        if not result["first_attempt"]:
            entry.setdefault("first_failures", []).append(result["first_failure"] or result["message"])
    for conditions in found.values():
        for entry in conditions.values():
            entry["causes"] = dict(Counter(_cause(f["message"]) for f in entry["failures"]).most_common())
            first = entry.pop("first_failures", [])
            entry["first_attempt_causes"] = dict(Counter(_cause(message) for message in first).most_common())
    print(f"{robot}: {len(jobs)} runs in {time.time() - started:.0f} s", file=sys.stderr)
    return found


def _cause(message: str) -> str:
    """A failure's message without its numbers: what kind of failure it was."""
    return "".join(c for c in message if not (c.isdigit() or c in ".-")).strip()[:90]


def plot(results: dict, path: Path) -> None:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    names = ("sequence", "sequence-by-block", "blocks", "ik")
    robots = list(results["robots"])
    figure, axes = plt.subplots(1, len(robots), figsize=(5.5 * len(robots), 3.4), squeeze=False)
    for panel, robot in zip(axes[0], robots, strict=True):
        found = results["robots"][robot]["evaluation"]
        for c, condition in enumerate(("unperturbed", "perturbed")):
            for m, name in enumerate(names):
                entry = found[name][condition]
                x = c + (m - 1.5) * 0.22
                panel.bar(
                    x - 0.06,
                    entry["success"] / entry["runs"],
                    0.12,
                    color=f"C{m}",
                    label=name if c == 0 else None,
                )
                panel.bar(x + 0.06, entry["first_attempt"] / entry["runs"], 0.12, color=f"C{m}", alpha=0.45)
        panel.axhline(0.95, color="grey", lw=0.8, ls="--")
        panel.set_xticks([0, 1], ["unperturbed", "perturbed (half pushed)"])
        panel.set_ylim(0, 1.05)
        panel.set_title(f"{robot}: task success (dark), first attempt (light)")
        panel.legend(fontsize=8, loc="lower left")
    axes[0][0].set_ylabel("share of held-out tasks")
    figure.tight_layout()
    figure.savefig(path, dpi=120)


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--robots", nargs="+", default=["aila", "ur5e"])
    parser.add_argument("--tasks", type=int, default=8)
    parser.add_argument("--budget", type=int, default=48)
    parser.add_argument("--count", type=int, default=200)
    parser.add_argument("--plain", type=int, default=100)
    parser.add_argument("--seed", type=int, default=2027)
    parser.add_argument("--workers", type=int, default=2)
    parser.add_argument("--work", type=Path, default=Path("/tmp/besman-sequences"))
    parser.add_argument("--json", action="store_true")
    parser.add_argument("--out", type=Path, default=ROOT / "docs" / "results" / "sequences.json")
    args = parser.parse_args(argv)
    results = {
        "settings": {k: v for k, v in vars(args).items() if k not in ("json", "out", "work")},
        "perturbations": task("pick-place").perturbations.describe(),
        "robots": {},
    }
    for robot in args.robots:
        trees = {}
        training = {}
        trained = []
        for refinement in REFINEMENTS:
            settings = LearnSettings(tasks=args.tasks, budget=args.budget, refinement=refinement)
            started = time.time()
            pool, refined = learn_pool(robot, refinement, settings, args.work)
            training[refinement] = {
                "minutes": round((time.time() - started) / 60, 1),
                **training_summary(refined),
            }
            trees[refinement] = pool / "tree.yaml"
            trained.append(training_taus(SkillTemplatePool(pool)))
        committed = ROOT / "examples" / "pools" / f"pick_place_{robot}"
        trees["blocks"] = committed / "tree.yaml"
        trees["ik"] = ROOT / "examples" / "trees" / "grasp_then_place.yaml"  # no learned parameter at all
        trained.append(training_taus(SkillTemplatePool(committed)))
        taus, sizes = held_out(robot, np.concatenate(trained), args.count, args.seed)
        results["robots"][robot] = {
            "training": training,
            "sizes": sizes,
            "evaluation": evaluate(trees, robot, taus, args.plain, args.seed, args.workers),
        }
    args.out.write_text(json.dumps(results, indent=1) + "\n")
    plot(results, args.out.with_suffix(".png"))
    if args.json:
        print(json.dumps(results, indent=1))
        return 0
    for robot, found in results["robots"].items():
        for name, conditions in found["evaluation"].items():
            for condition, entry in conditions.items():
                n = entry["runs"]
                pushed = entry["pushed"]
                extra = (
                    f"; pushed: task {pushed['success']}/{pushed['runs']}, "
                    f"first {pushed['first_attempt']}/{pushed['runs']}"
                    if pushed["runs"]
                    else ""
                )
                print(
                    f"{robot:5s} {name:18s} {condition:11s} task {entry['success']}/{n} "
                    f"({entry['success'] / n:.2f}), first attempt {entry['first_attempt']}/{n} "
                    f"({entry['first_attempt'] / n:.2f}){extra}"
                )
                for cause, times in entry["causes"].items():
                    print(f"      {times:3d} x {cause}")
                for cause, times in entry["first_attempt_causes"].items():
                    print(f"      first attempt: {times:3d} x {cause}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
