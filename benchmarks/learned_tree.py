"""The tree that ``besman learn`` writes from the recordings (``POOL/tree.yaml``) on unseen tasks, as is and
perturbed.

    python benchmarks/learned_tree.py [--json] [--robots aila ur5e] [--count 30] [--seed 3037]
                                      [--workers 2] [--out docs/results/learned_tree.json]

Per robot, the committed pool's learned tree (``examples/pools/pick_place_<robot>/tree.yaml``, run with no
edit) on ``count`` held-out pick-and-place taus (drawn as ``benchmarks/learned.py`` draws them: positions
and yaws over the whole task box, object sizes no training task had, boxes and cylinders in turn; none is
a training task), three times each: unperturbed, with perception errors (``--perturb perception``: the
object's pose perceived up to 1.5 cm and 5 deg off at every look) and with the push as well (``push``: 1-3
cm half-way through the reach). Episode k's seed (a child of ``seed``) draws the object's mass and friction
and the perturbations, the same for every mode.

Reported per robot and mode: task success (the task's rule), first-attempt success (the task succeeded
with one reach and one carry: no try of the grasp or of the place failed) and the failures with their
messages; JSON with ``--json`` (and always to ``--out``), a bar chart beside it (``.png``).
"""

from __future__ import annotations

import argparse
import json
import multiprocessing
import sys
from concurrent.futures import ProcessPoolExecutor
from pathlib import Path

from learned import held_out, training_taus

from besman.core.seeds import child_seed
from besman.skills import SkillTemplatePool
from besman.tasks import task

ROOT = Path(__file__).resolve().parent.parent
MODES = (None, "perception", "push")
TARGET = 0.95  # the bar for the learned tree's task success on unseen tasks


def episode(arguments: tuple) -> dict:
    """One run of the learned tree: success, whether the first attempt did it, and the message."""
    from besman.tasks.episodes import MotionTrail
    from besman.tasks.running import run

    tree, robot, tau, seed, mode = arguments
    trail = MotionTrail()
    summary = run(
        "pick-place",
        tree,
        robot=robot,
        values=task("pick-place").split(tau),
        seed=seed,
        perturb=mode,
        observe=trail,
    )
    names = [motion.name for motion in trail.motions]
    first = summary.success and names.count("reach") == 1 and names.count("carry") == 1
    failed = next((m for m in trail.motions if m.status.value == "failed"), None)
    return {
        "success": bool(summary.success),
        "first_attempt": bool(first),
        "reaches": names.count("reach"),
        "first_failure": None if failed is None else f"{failed.name}: {failed.message}",
        "outcome": summary.outcome,
        "message": summary.message,
    }


def measure(robot: str, count: int, seed: int, workers: int) -> dict:
    pool = ROOT / "examples" / "pools" / f"pick_place_{robot}"
    tree = pool / "tree.yaml"
    taus, sizes = held_out(robot, training_taus(SkillTemplatePool(pool)), count, seed)
    jobs = [
        (str(tree), robot, tau, child_seed(seed, 2, k), mode) for mode in MODES for k, tau in enumerate(taus)
    ]
    context = multiprocessing.get_context("spawn")
    with ProcessPoolExecutor(workers, mp_context=context) as executor:
        results = list(executor.map(episode, jobs))
    report = {}
    for index, mode in enumerate(MODES):
        runs = results[index * count : (index + 1) * count]
        report[mode or "none"] = {
            "success": sum(r["success"] for r in runs),
            "first_attempt": sum(r["first_attempt"] for r in runs),
            "runs": count,
            "failures": [
                {"tau": taus[k].round(4).tolist(), "outcome": r["outcome"], "message": r["message"]}
                for k, r in enumerate(runs)
                if not r["success"]
            ],
        }
    return {"tree": str(tree.relative_to(ROOT)), "sizes": sizes, "modes": report}


def plot(results: dict, path: Path) -> None:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    figure, axes = plt.subplots(figsize=(7, 3.2))
    width, labels = 0.13, [mode or "none" for mode in MODES]
    for r, (robot, found) in enumerate(results["robots"].items()):
        for m, mode in enumerate(labels):
            entry = found["modes"][mode]
            x = m + (r - 0.5) * 2.2 * width
            axes.bar(x - width / 2, entry["success"] / entry["runs"], width, color=f"C{r}", label=None)
            axes.bar(x + width / 2, entry["first_attempt"] / entry["runs"], width, color=f"C{r}", alpha=0.45)
        axes.bar(0, 0, color=f"C{r}", label=f"{robot}: task (dark), first attempt (light)")
    axes.axhline(TARGET, color="grey", lw=0.8, ls="--")
    axes.set_xticks(range(len(labels)), ["unperturbed", "perception error", "perception + push"])
    axes.set_ylim(0, 1.05)
    axes.set_ylabel("share of unseen tasks")
    axes.set_title("The tree learned from the recordings (POOL/tree.yaml), zero-shot")
    axes.legend(fontsize=8, loc="lower left")
    figure.tight_layout()
    figure.savefig(path, dpi=120)


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--robots", nargs="+", default=["aila", "ur5e"])
    parser.add_argument("--count", type=int, default=30)
    parser.add_argument("--seed", type=int, default=3037)
    parser.add_argument("--workers", type=int, default=2)
    parser.add_argument("--json", action="store_true")
    parser.add_argument("--out", type=Path, default=ROOT / "docs" / "results" / "learned_tree.json")
    args = parser.parse_args(argv)
    results = {
        "count": args.count,
        "seed": args.seed,
        "perturbations": task("pick-place").perturbations.describe(),
        "robots": {robot: measure(robot, args.count, args.seed, args.workers) for robot in args.robots},
    }
    args.out.write_text(json.dumps(results, indent=1) + "\n")
    plot(results, args.out.with_suffix(".png"))
    if args.json:
        print(json.dumps(results, indent=1))
        return 0
    for robot, found in results["robots"].items():
        for mode, entry in found["modes"].items():
            n = entry["runs"]
            print(
                f"{robot:8s} {mode:11s} task {entry['success']}/{n} ({entry['success'] / n:.2f}), "
                f"first attempt {entry['first_attempt']}/{n} ({entry['first_attempt'] / n:.2f})"
            )
            for failure in entry["failures"]:
                print(f"    {failure['tau']}: {failure['outcome']} | {failure['message']}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
