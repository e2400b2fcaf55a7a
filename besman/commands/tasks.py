"""`besman tasks` and `besman experiment`: the tasks' values and ranges, and the paper's experiments."""

from __future__ import annotations

import argparse
import json
import sys
from pathlib import Path

from besman.commands.options import COUNT
from besman.core.errors import InputError


def _tasks_list(args: argparse.Namespace) -> int:
    from besman.tasks import TASKS

    for entry in TASKS.values():
        print(f"{entry.name}\t{entry.title} (default robot: {entry.robot}; tree: {entry.tree or 'none'})")
    return 0


def _tasks_show(args: argparse.Namespace) -> int:
    from besman.tasks import task

    facts = task(args.name).describe(args.robot)  # unknown names and unfit robots are named
    if args.json:
        print(json.dumps(facts, indent=2))
        return 0
    print(f"{facts['task']} on {facts['robot']}: {facts['title']}")
    print(f"randomised: {facts['randomised']}")
    print(f"success: {facts['success']}")
    print(f"default tree: {facts['tree'] or 'none'}")
    for column in facts["tau"]:  # name, range and unit; a choice's index and name
        low, high = column["range"]
        unit = f" {column['unit']}" if column["unit"] else ""
        choices = ", ".join(f"{index} = {name}" for index, name in enumerate(column.get("choices", ())))
        print(f"{column['name']}\t[{low:g}, {high:g}]{unit}" + (f": {choices}" if choices else ""))
    if "objects" in facts:
        objects = facts["objects"]
        print(
            f"objects: {' or '.join(objects['shapes'])}, width {_span(objects['width_m'])} m, height "
            f"{_span(objects['height_m'])} m, mass {_span(objects['mass_kg'])} kg, friction "
            f"{_span(objects['friction'])}; the gripper opens {objects['gripper_opening_m']:g} m"
        )
    return 0


def _span(numbers) -> str:
    return f"{numbers[0]:g}-{numbers[1]:g}"


def _experiment_throwing(args: argparse.Namespace) -> int:
    from besman.experiments.throwing.experiment import Experiment, ExperimentConfig

    config = (
        ExperimentConfig.quick(args.seeds or 1) if args.quick else ExperimentConfig(seeds=args.seeds or 3)
    )
    results = Experiment(config, Path(args.out), backend=args.backend).run()
    if args.quick:
        print(
            f"--quick: every stage at a small size ({config.seeds} seed(s), K in {config.ks}, a "
            f"{config.grid} x {config.grid} grid, {config.training_rollouts} training rollouts): the checks "
            "below are the full run's, at bars this size is not meant to reach, so FAILS here is expected "
            "and says nothing of the method (the full run's verdicts: docs/throwing.md)"
        )
    for kind in ("claims", "goals", "acceptance"):
        for name, facts in results[kind].items():
            numbers = ", ".join(
                f"{k}={_rounded(v)}" for k, v in facts.items() if k not in ("holds", "comparisons")
            )
            print(f"{'holds' if facts['holds'] else 'FAILS'}\t{kind}: {name}: {numbers}")
    print(f"wrote {Path(args.out) / 'results.json'}, fig5_top.png, fig5_bottom.png, fig_field.png")
    return 0


# The template studies (besman.experiments.template_study) by command name: the module with the task's STUDY
# and what it is (the modules import MuJoCo: named here, imported when run).
TEMPLATE_STUDIES = {
    "ball-in-cup": ("besman.experiments.ball_in_cup", "ball in a cup on the UR5e"),
    "puck-strike": ("besman.experiments.puck_strike", "the puck strike on the UR5e"),
}


def _experiment_template_study(args: argparse.Namespace) -> int:
    import importlib

    from besman.core.storage import check_output, write_atomically
    from besman.experiments.template_study import Experiment, report
    from besman.experiments.template_study_plots import plot

    out = Path(args.out)
    written = check_output(out / "results.json", option="--out", suffixes=(".json",))
    if args.pool is not None and Path(args.pool).exists() and not Path(args.pool).is_dir():
        raise InputError(f"--pool {args.pool}: a file, not a pool's folder")
    study = importlib.import_module(TEMPLATE_STUDIES[args.experiment_command][0]).STUDY
    config = study.quick if args.quick else study.config
    results = Experiment(study, config, progress=True).run(None if args.pool is None else Path(args.pool))
    write_atomically(written, (json.dumps(results, indent=1) + "\n").encode())
    figures = plot(results, out)
    print(json.dumps(results, indent=1) if args.json else report(results))
    print(f"wrote {written}, " + ", ".join(figure.name for figure in figures), file=sys.stderr)
    return 0


def _rounded(value):
    """Numbers to three significant digits, also inside the per-K tables of the acceptance."""
    if isinstance(value, float):
        return f"{value:.3g}"
    if isinstance(value, dict):
        return "{" + ", ".join(f"{k}: {_rounded(v)}" for k, v in value.items()) + "}"
    return str(value)


def register(commands) -> None:
    """Adds this module's commands to the parser's subcommands."""
    tasks = commands.add_parser("tasks", help="the task registry: list the tasks, show one on a robot")
    tasks.set_defaults(handler=_tasks_list)
    task_commands = tasks.add_subparsers(dest="tasks_command", metavar="ACTION")
    task_show = task_commands.add_parser(
        "show",
        help="a task on a robot: what it is, what is randomised, success, each number of tau with its unit "
        "(lengths in m, yaws in degrees) and range, a choice's names (a shape), the objects it draws",
    )
    task_show.add_argument("name")
    task_show.add_argument("--robot", default=None, help="the robot (default: the task's own)")
    task_show.add_argument(
        "--json", action="store_true", help="everything as JSON: its values, tau's columns, its own facts"
    )
    task_show.set_defaults(handler=_tasks_show)

    experiment = commands.add_parser("experiment", help="the paper's experiments")
    experiment_commands = experiment.add_subparsers(dest="experiment_command", metavar="NAME", required=True)
    throwing = experiment_commands.add_parser(
        "throwing", help="skill templates on PA-10 throwing (Fig. 5) and the field: results.json, three plots"
    )
    throwing.add_argument(
        "--quick",
        action="store_true",
        help="a small run (3 x 3 grid, K up to 4; 40 s on 2 cores, 2026-11-27)",
    )
    throwing.add_argument("--seeds", type=COUNT, help="independent repetitions (default 3; 1 with --quick)")
    throwing.add_argument(
        "--backend",
        choices=("threads", "ray"),
        default="threads",
        help="where rollouts run: threads (local cores, default) or ray (a local Ray that listens on "
        "127.0.0.1 only, or the cluster that RAY_ADDRESS names; see docs/learning.md)",
    )
    throwing.add_argument("--out", required=True, help="the results directory (an interrupted run resumes)")
    throwing.set_defaults(handler=_experiment_throwing)
    for name, (_, what) in TEMPLATE_STUDIES.items():
        study = experiment_commands.add_parser(
            name,
            help=f"{what}: the scripted baseline, CMA-ES from the demonstration, the skill template over tau "
            "(results.json, two plots)",
        )
        study.add_argument("--quick", action="store_true", help="a small run for tests (under a minute)")
        study.add_argument("--out", required=True, help="the results directory")
        study.add_argument("--pool", help="store seed 0's template of all K training tasks in this pool")
        study.add_argument("--json", action="store_true", help="print results.json to stdout")
        study.set_defaults(handler=_experiment_template_study)
