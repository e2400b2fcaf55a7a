"""`besman learn`: from a folder of human recordings, or a dataset of the robot's own episodes, to a skill
template pool of a task's building blocks."""

from __future__ import annotations

import argparse
import sys

from besman.commands.options import COUNT, SEED


def _roles(text: str) -> tuple[tuple[str, str], ...]:
    pairs = []
    for item in filter(None, text.split(",")):
        block, _, label = item.partition("=")
        if not label:
            raise argparse.ArgumentTypeError(f"--roles takes BLOCK=LABEL,..., got {item!r}")
        pairs.append((block.strip(), label.strip()))
    return tuple(pairs)


def _learn(args: argparse.Namespace) -> int:
    import numpy as np

    from besman.core.errors import InputError
    from besman.learning.pipeline.end_to_end import LearnSettings, learn
    from besman.tasks import DEFAULT, TASKS, task

    chosen = task(args.task or DEFAULT)  # an unknown name is refused with the list, before any work
    robot = chosen.check_robot(args.robot)
    blocks = chosen.building_blocks(robot)
    if blocks is None:
        learnable = [name for name, entry in TASKS.items() if entry.building_blocks(entry.robot) is not None]
        raise InputError(
            f"task {chosen.name} has no building blocks to learn; tasks that learn: {', '.join(learnable)}"
        )
    settings = LearnSettings(
        tasks=args.training_tasks,
        budget=args.budget,
        seed=args.seed,
        backend=args.backend,
        n_blocks=args.blocks,
        examples=tuple(args.examples),
        roles=args.roles,
        refinement=args.refinement,
        optimizer=args.optimizer,
    )
    result = learn(args.demos, args.out, settings, blocks=blocks, force=args.force)
    from besman.learning.pipeline.sequence_refinement import subgoals
    from besman.trees.learned import write_learned_tree

    tree = write_learned_tree(
        result.pool,
        result.structure,
        task=blocks.task,
        object=blocks.object,
        target=blocks.target,
        subgoals=subgoals(result.refined),
    )
    print(f"pool {result.pool}: templates {', '.join(result.templates)}")
    print(f"  tree {tree}: {' -> '.join(result.structure.order)} ({result.structure.decided})")
    for block, runs in result.refined.items():
        refined = sum(run["outcome"]["success"] for run in runs)
        retargeted = sum(run["start_outcome"]["success"] for run in runs)
        verdicts = [run["acceptance"] for run in runs if "acceptance" in run]  # older work files have none
        line = f"  {block}: {len(runs)} training tasks, succeeded retargeted {retargeted}, refined {refined}"
        if verdicts:
            gained, noise = (np.mean([v[key] for v in verdicts]) for key in ("improvement", "noise"))
            kept = sum(v["accepted"] for v in verdicts)
            line += f"; refinement kept in {kept} (reward gained {gained:.3g}, noise {noise:.3g} on average)"
        print(line)
    print("figures: " + ", ".join(str(path) for path in result.figures), file=sys.stderr)
    return 0


def register(commands) -> None:
    """Adds this module's commands to the parser's subcommands."""
    learn = commands.add_parser(
        "learn",
        help="learn skill templates from human recordings or a robot's dataset (segment, label, imitate, "
        "retarget, refine, pool)",
    )
    learn.add_argument(
        "--demos",
        required=True,
        help="a folder of recordings (.tsv, .csv, .npz) of people, or a LeRobot v3.0 dataset of the robot's "
        "own episodes (besman record; docs/datasets.md)",
    )
    learn.add_argument("--out", required=True, help="the pool folder (resumed if a run was interrupted)")
    learn.add_argument(
        "--task",
        default=None,
        help="the task whose building blocks to learn (default: the first that besman tasks lists)",
    )
    learn.add_argument("--robot", help="the robot (default: the task's)")
    learn.add_argument(
        "--training-tasks",
        type=COUNT,
        default=8,
        metavar="K",
        help="training tasks K per building block (default 8; formerly --tasks)",
    )
    learn.add_argument("--budget", type=COUNT, default=48, help="rollouts per training task (default 48)")
    learn.add_argument("--seed", type=SEED, default=0)
    learn.add_argument(
        "--refinement",
        choices=("blocks", "sequence", "sequence-by-block"),
        default="blocks",
        help="blocks: each block alone from the planned starts (default); sequence: all blocks and their "
        "subgoals together on whole-task rollouts with the task's perturbations, each credited with its "
        "cost-to-go; sequence-by-block: the same rollouts, one block after the other (see docs/learning.md)",
    )
    learn.add_argument(
        "--optimizer",
        default="cmaes",
        metavar="NAME",
        help="the policy search's optimiser: cmaes (default), xnes, or one an installed package adds "
        "(docs/optimizers.md)",
    )
    learn.add_argument(
        "--backend",
        choices=("threads", "ray"),
        default="threads",
        help="where rollouts run: threads (local cores, default) or ray (a local Ray that listens on "
        "127.0.0.1 only, or the cluster that RAY_ADDRESS names; see docs/learning.md)",
    )
    learn.add_argument("--blocks", type=COUNT, default=6, help="building blocks to cluster into (default 6)")
    learn.add_argument(
        "--examples", nargs="+", default=[], metavar="FILE", help="annotated recordings: label by them (1-NN)"
    )
    learn.add_argument(
        "--roles",
        type=_roles,
        default=(),
        metavar="BLOCK=LABEL,...",
        help="the label that plays each of the task's blocks (default: the task's own, a cluster block1... "
        "in task order, or a label of the --examples; see docs/learning.md)",
    )
    learn.add_argument(
        "--force",
        action="store_true",
        help="start over: replace a pool learned for another task or robot or with other settings (its "
        "stage caches only), or write into a folder that holds other files (removing none of them)",
    )
    learn.set_defaults(handler=_learn)
