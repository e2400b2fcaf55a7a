"""`besman tasks` and `besman experiment`: the tasks' parameter bounds and the paper's experiments."""

from __future__ import annotations

import argparse
import json
from pathlib import Path

from besman.skills.errors import InputError

TASKS = ("pick-place", "throwing", "throwing-hardware")


def _tasks_show(args: argparse.Namespace) -> int:
    if args.name == "pick-place":
        from besman.sim.pick_place import PICK_PLACE_BOUNDS as bounds
    elif args.name in ("throwing", "throwing-hardware"):
        from besman.sim.throwing import HARDWARE_BOUNDS, PAPER_BOUNDS

        bounds = PAPER_BOUNDS if args.name == "throwing" else HARDWARE_BOUNDS
    else:
        raise InputError(f"unknown task {args.name!r}; tasks: {', '.join(TASKS)}")
    if args.json:
        print(json.dumps({"task": args.name, "bounds": bounds.as_dict()}, indent=2))
    else:
        for name, (low, high) in bounds.as_dict().items():
            print(f"{name}\t[{low:g}, {high:g}]")
    return 0


def _experiment_throwing(args: argparse.Namespace) -> int:
    from besman.learning.throwing_experiment import Experiment, ExperimentConfig

    config = (
        ExperimentConfig.quick(args.seeds or 1) if args.quick else ExperimentConfig(seeds=args.seeds or 3)
    )
    results = Experiment(config, Path(args.out), backend=args.backend).run()
    for kind in ("claims", "goals"):
        for name, facts in results[kind].items():
            numbers = ", ".join(
                f"{k}={v:.3g}" if isinstance(v, float) else f"{k}={v}"
                for k, v in facts.items()
                if k not in ("holds", "comparisons")
            )
            print(f"{'holds' if facts['holds'] else 'FAILS'}\t{name}: {numbers}")
    print(f"wrote {Path(args.out) / 'results.json'}, fig5_top.png, fig5_bottom.png, fig_field.png")
    return 0


def register(commands) -> None:
    """Adds this module's commands to the parser's subcommands."""
    tasks = commands.add_parser("tasks", help="the tasks' parameters")
    task_commands = tasks.add_subparsers(dest="tasks_command", metavar="ACTION", required=True)
    task_show = task_commands.add_parser("show", help=f"a task's parameter bounds ({', '.join(TASKS)})")
    task_show.add_argument("name")
    task_show.add_argument("--json", action="store_true")
    task_show.set_defaults(handler=_tasks_show)

    experiment = commands.add_parser("experiment", help="the paper's experiments")
    experiment_commands = experiment.add_subparsers(dest="experiment_command", metavar="NAME", required=True)
    throwing = experiment_commands.add_parser(
        "throwing", help="skill templates on PA-10 throwing (Fig. 5) and the field: results.json, three plots"
    )
    throwing.add_argument(
        "--quick", action="store_true", help="a small run (3 x 3 grid, K up to 4; about a minute)"
    )
    throwing.add_argument("--seeds", type=int, help="independent repetitions (default 3; 1 with --quick)")
    throwing.add_argument("--backend", choices=("threads", "ray"), default="threads")
    throwing.add_argument("--out", required=True, help="the results directory (an interrupted run resumes)")
    throwing.set_defaults(handler=_experiment_throwing)
