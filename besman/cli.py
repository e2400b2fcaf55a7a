"""besman: robots learn reusable manipulation skills and run them as behaviour trees (the command line).

One module on purpose (over 450 lines): each subcommand is a handler of a few lines that imports its package
only when it runs (``besman --help`` stays fast), beside the parser that names them all.
"""

from __future__ import annotations

import argparse
import json
import math
import os
import sys
import time
from collections.abc import Sequence
from pathlib import Path

from besman._version import __version__
from besman.skills.errors import InputError
from besman.skills.storage import check_output


def _robot_table(name: str) -> dict:
    """The JSON-ready description of a robot: groups, and per joint its limits and actuator."""
    from besman.robots import load

    robot = load(name)
    joints = []
    for group in robot.groups.values():
        for i, joint in enumerate(group.joints):
            joints.append(
                {
                    "group": group.name,
                    "name": joint,
                    "lower": float(group.lower[i]),
                    "upper": float(group.upper[i]),
                    "velocity": float(group.velocity[i]),
                    "acceleration": float(group.acceleration[i]),
                    "jerk": float(group.jerk[i]),
                }
            )
    return {
        "name": robot.name,
        "title": robot.description.title,
        "model": str(robot.description.model_file),
        "nq": robot.model.nq,
        "nu": robot.model.nu,
        "timestep": robot.model.opt.timestep,
        "groups": {
            group.name: {
                "joints": list(group.joints),
                "actuators": list(group.actuators),
                "site": group.site,
                "equalities": list(group.equalities),
            }
            for group in robot.groups.values()
        },
        "joints": joints,
    }


def _robots_list(args: argparse.Namespace) -> int:
    from besman.robots import available, load

    for name in available():
        print(f"{name}\t{load(name).description.title}")
    return 0


def _robots_show(args: argparse.Namespace) -> int:
    table = _robot_table(args.name)
    if args.json:
        print(json.dumps(table, indent=2))
        return 0
    from rich.console import Console
    from rich.table import Table

    view = Table(title=f"{table['name']}: {table['title']}")
    for column in ("group", "joint", "lower", "upper", "velocity", "acceleration", "jerk"):
        view.add_column(column, justify="left" if column in ("group", "joint") else "right")
    for joint in table["joints"]:
        view.add_row(
            joint["group"],
            joint["name"],
            *(f"{joint[key]:.4g}" for key in ("lower", "upper", "velocity", "acceleration", "jerk")),
        )
    console = Console(width=None if sys.stdout.isatty() else 120)
    console.print(view)
    console.print("units: rad or m; velocity per s, acceleration per s^2, jerk per s^3")
    for name, group in table["groups"].items():
        console.print(f"{name}: site={group['site']}, actuators={', '.join(group['actuators']) or '-'}")
    return 0


def _robots_render(args: argparse.Namespace) -> int:
    from besman.robots import load
    from besman.robots.render import png_path, render, save_png

    out = png_path(args.out)  # fail before the work, not after it
    image = render(load(args.name), width=args.width, height=args.height, keyframe=args.keyframe)
    print(save_png(image, out))
    return 0


def _tree_show(args: argparse.Namespace) -> int:
    import py_trees

    from besman.trees import load_tree

    print(py_trees.display.unicode_tree(load_tree(args.file)))
    return 0


def _tree_render(args: argparse.Namespace) -> int:
    import py_trees

    from besman.skills.storage import write_atomically
    from besman.trees import load_tree

    formats = {".svg": "svg", ".png": "png", ".dot": None}  # .dot: the DOT source itself, no Graphviz
    out = check_output(args.out, option="--out", suffixes=tuple(formats), inputs=(args.file,))
    graph = py_trees.display.dot_tree(load_tree(args.file))
    kind = formats[out.suffix.lower()]
    if kind is None:
        data = graph.to_string().encode("utf-8")
    else:
        try:
            data = graph.create(format=kind)
        except (FileNotFoundError, OSError, AssertionError) as error:  # pydot asserts on dot's exit code
            raise RuntimeError(
                f"rendering needs Graphviz's dot program (apt-get install graphviz): {error}"
            ) from None
    print(write_atomically(out, data))
    return 0


def _parse_sets(pairs: Sequence[str]) -> dict[str, tuple[float, ...]]:
    values = {}
    for pair in pairs:
        name, equals, text = pair.partition("=")
        if not equals or not name:
            raise InputError(f"--set {pair!r}: expected name=value[,value...]")
        if name in values:
            raise InputError(f"--set {name}: given twice")
        try:
            values[name] = tuple(float(v) for v in text.split(","))
        except ValueError:
            raise InputError(f"--set {pair!r}: the values must be numbers separated by commas") from None
        if not all(math.isfinite(v) for v in values[name]):
            raise InputError(f"--set {pair!r}: the values must be finite numbers")
    return values


def _print_summary(summary: dict, as_json: bool) -> None:
    if as_json:
        print(json.dumps(summary, indent=2))
        return
    error = summary["placement_error_m"]
    outcome = (
        f"placement error {error * 100:.1f} cm"
        if error is not None
        else "box at ({:.3f}, {:.3f}, {:.3f}) m".format(*summary["box_position"])
    )
    print(
        f"{summary['status']}: {outcome}, "
        f"{summary['sim_time_s']:.1f} s simulated in {summary['wall_time_s']:.1f} s, {summary['ticks']} ticks"
    )
    if summary["failed_node"]:
        print(f"failed at {summary['failed_node']}: {summary['message']}")


def _tabletop(args: argparse.Namespace, tree, values: dict, log) -> tuple[dict, list]:
    """Runs ``tree`` on AILA's tabletop; with --view inside a browser session that stays open after the run
    (returned in the list, for :func:`_serve`)."""
    from besman.trees.tabletop import run_on_tabletop, summary

    if not args.view:
        return run_on_tabletop(tree, values, seed=getattr(args, "seed", None), log=log), []
    from besman.trees.session import Session

    session = Session(
        tree,
        values,
        seed=getattr(args, "seed", None),
        speed=args.speed,
        viewer_options={"host": args.host, "port": args.port},
    )
    print(
        f"viewer: {session.viewer.url} (the run goes at {args.speed:g}x real time)",
        file=sys.stderr,
        flush=True,
    )
    try:
        result = session.start(log=log)
    except BaseException:
        session.close()
        raise
    return summary(session.runner, session.values, result), [session]


def _serve(viewers: list, code: int) -> int:
    """Keeps a viewer (anything with ``url`` and ``close()``) open until Ctrl-C."""
    if not viewers:
        return code
    print(f"the viewer stays at {viewers[0].url} until Ctrl-C", file=sys.stderr, flush=True)
    try:
        while True:
            time.sleep(3600)
    except KeyboardInterrupt:
        viewers[0].close()
        return code


def _view(args: argparse.Namespace) -> int:
    options = {"host": args.host, "port": args.port}
    if args.throw:
        return _view_throw(args, options)
    from besman.trees.watching import Replay

    replay = Replay(args.replay, options)
    print(
        f"replay of {args.replay} ({len(replay.records)} ticks): {replay.viewer.url}",
        file=sys.stderr,
        flush=True,
    )
    return _serve([replay], 0)


def _view_throw(args: argparse.Namespace, options: dict) -> int:
    from besman.sim.throwing_view import ThrowingView
    from besman.skills.pool import SkillTemplatePool

    pool = SkillTemplatePool(args.throw)
    if args.template not in pool:
        raise InputError(
            f"--throw {args.throw}: no template {args.template!r} (it has: {', '.join(pool) or 'none'})"
        )
    target = None
    if args.target is not None:
        try:
            target = [float(v) for v in args.target.split(",")]
        except ValueError:
            raise InputError(f"--target {args.target!r}: expected two numbers, X,Y") from None
    view = ThrowingView(pool[args.template], target, options)
    print(
        f"throwing template {args.template!r}: {view.url} (drag the target to throw again)",
        file=sys.stderr,
        flush=True,
    )
    view.throw()
    print(view.status.content)
    return _serve([view], 0)


def _run(args: argparse.Namespace) -> int:

    if args.log:
        check_output(args.log, option="--log", suffixes=(".jsonl",), inputs=(args.file,))
    summary, viewers = _tabletop(args, args.file, _parse_sets(args.set), args.log)
    _print_summary(summary, args.json)
    return _serve(viewers, 0 if summary["status"] == "SUCCESS" else 1)


def _demo(args: argparse.Namespace) -> int:
    from besman.trees import grasp_then_place

    if args.log:
        check_output(args.log, option="--log", suffixes=(".jsonl",))
    if not args.json:  # --json prints the summary alone
        print("AILA grasps the box on the table and places it on the shelf (grasp-then-place tree)")
    summary, viewers = _tabletop(
        args, grasp_then_place(), {"object": (0.55, -0.08), "place": (0.54, -0.41)}, args.log
    )
    _print_summary(summary, args.json)
    if not args.json:
        print(
            "next: watch it in the browser (besman demo --view), or run the same tree as a file elsewhere on "
            "the table with a log:\n"
            "  besman run examples/trees/grasp_then_place.yaml --set object=0.5,-0.05 --set place=0.58,-0.44 "
            "--log run.jsonl"
        )
    return _serve(viewers, 0 if summary["status"] == "SUCCESS" else 1)


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


def _segment(args: argparse.Namespace) -> int:
    from besman.learning import load
    from besman.learning.segmentation import segment

    if args.example_labels and not args.examples:
        raise InputError("--example-labels chooses among the segments of --examples; give --examples too")
    if args.plot:
        check_output(
            args.plot, option="--plot", suffixes=(".png",), inputs=(args.file, *(args.examples or ()))
        )
    demo = load(args.file)
    from tqdm import tqdm

    from besman.learning.segmentation import EXACT_UP_TO

    samples = int(demo.duration * 20.0)  # at segment()'s signal rate; pruned inference reports progress
    with tqdm(
        total=samples, desc="segmenting", unit="sample", leave=False, disable=samples <= EXACT_UP_TO
    ) as bar:
        segmentation = segment(
            demo,
            marker=args.marker,
            max_particles=None if args.exact else (args.max_particles or "auto"),
            progress=bar.update,
        )
    labels = _few_shot_labels(args, demo, segmentation) if args.examples else [None] * len(segmentation)
    frames = [int(frame) for frame in segmentation.frames]
    times = [float(time) for time in segmentation.times]
    result = {
        "segments": [
            {
                "start_frame": frames[k],
                "end_frame": frames[k + 1],
                "start_time": times[k],
                "end_time": times[k + 1],
                "label": labels[k],
                "model": segmentation.models[k],
            }
            for k in range(len(segmentation))
        ],
        "boundaries_frame": frames,
    }
    if args.plot:
        from besman.learning.segmentation_plot import plot_segmentation

        plot_segmentation(demo, segmentation, args.plot)
    if args.json:
        print(json.dumps(result, indent=2))
    else:
        for k, entry in enumerate(result["segments"]):
            print(
                f"{k:2d}  frames {entry['start_frame']}-{entry['end_frame']}  "
                f"{entry['start_time']:.2f}-{entry['end_time']:.2f} s  {entry['model']}"
                + (f"  {entry['label']}" if entry["label"] else "")
            )
    return 0


def _few_shot_labels(args: argparse.Namespace, demo, segmentation) -> list[str | None]:
    """Labels of the movements found: those of the nearest annotated segments of the example recordings
    (holds stay unlabelled)."""
    from besman.learning import DemonstrationError, load
    from besman.learning.labelling import ground_truth_segments, label_few_shot, segments_of

    wanted = args.example_labels.split(",") if args.example_labels else None
    examples = []
    for path in args.examples:
        annotated = ground_truth_segments(load(path), wanted)
        if not annotated:
            raise DemonstrationError(
                f"{path}: no annotated segments{' with labels ' + args.example_labels if wanted else ''} "
                "(expected a *_manually_segmented.json beside it)"
            )
        examples += annotated
    found = segments_of(demo, segmentation)
    moving = [k for k, hold in enumerate(segmentation.holds) if not hold]
    labels: list[str | None] = [None] * len(found)
    if not moving:
        return labels
    for k, label in zip(
        moving, label_few_shot(examples, [found[k] for k in moving], marker=args.marker), strict=True
    ):
        labels[k] = label
    return labels


def _demos_show(args: argparse.Namespace) -> int:
    from besman.learning import load

    demo = load(args.file)
    summary = {
        "file": str(args.file),
        "duration_s": demo.duration,
        "rate_hz": demo.rate,
        "samples": len(demo.times),
        "frames": [int(demo.frames[0]), int(demo.frames[-1])],
        "units": demo.units,
        "markers": {name: {"gaps": demo.gaps(name)} for name in demo.channels},
        "ground_truth_segments": len(demo.segments),
    }
    if args.json:
        print(json.dumps(summary, indent=2))
        return 0
    print(
        f"{summary['file']}: {demo.duration:.2f} s at {demo.rate:.1f} Hz, {len(demo.times)} samples "
        f"(frames {demo.frames[0]}-{demo.frames[-1]}), {len(demo.segments)} ground-truth segments"
    )
    for name in demo.channels:
        gaps = demo.gaps(name)
        missing = sum(last - first + 1 for first, last in gaps)
        detail = ", ".join(f"{first}-{last}" for first, last in gaps[:5]) + (" ..." if len(gaps) > 5 else "")
        print(f"  {name}: {len(gaps)} gaps, {missing} frames missing" + (f" ({detail})" if gaps else ""))
    return 0


def _pool_ls(args: argparse.Namespace) -> int:
    from besman.skills.pool import PoolError, SkillTemplatePool

    pool = SkillTemplatePool(args.directory)
    if not Path(args.directory).is_dir():
        raise InputError(f"{args.directory}: no such pool directory")
    broken = 0
    for name in pool:
        try:
            template = pool[name]
        except PoolError as error:
            broken += 1
            print(f"{name}\tunreadable: {error}")
            continue
        box = ", ".join(f"{n} [{lo:g}, {hi:g}]" for n, (lo, hi) in template.box.as_dict().items())
        size = template.thetas.shape[1]
        print(f"{name}\t{template.task or '-'}\tK={len(template.taus)}\ttheta {size}\ttau {box}")
    return 1 if broken else 0


def _pool_show(args: argparse.Namespace) -> int:
    from besman.skills.pool import SkillTemplatePool, summary

    pool = SkillTemplatePool(args.directory)
    if args.name not in pool:
        raise InputError(
            f"{args.directory}: the pool has no template {args.name!r} (has: {', '.join(pool) or 'none'})"
        )
    facts = summary(pool[args.name])
    if args.json:
        print(json.dumps(facts, indent=2))
    else:
        for key, value in facts.items():
            if key != "hyperparameters":
                print(f"{key}\t{value}")
    return 0


def _experiment_throwing(args: argparse.Namespace) -> int:
    from besman.learning.throwing_experiment import Experiment, ExperimentConfig

    config = (
        ExperimentConfig.quick(args.seeds or 1) if args.quick else ExperimentConfig(seeds=args.seeds or 3)
    )
    results = Experiment(config, Path(args.out), backend=args.backend).run()
    for claim, facts in results["claims"].items():
        numbers = ", ".join(
            f"{k}={v:.3g}" if isinstance(v, float) else f"{k}={v}" for k, v in facts.items() if k != "holds"
        )
        print(f"{'holds' if facts['holds'] else 'FAILS'}\t{claim}: {numbers}")
    print(f"wrote {Path(args.out) / 'results.json'}, fig5_top.png, fig5_bottom.png")
    return 0


def _view_options(command: argparse.ArgumentParser) -> None:
    view = command.add_argument_group("browser viewer")
    view.add_argument("--view", action="store_true", help="watch the run in the browser (viser)")
    view.add_argument(
        "--host", default="127.0.0.1", help="the viewer's address (default 127.0.0.1: this machine)"
    )
    view.add_argument("--port", type=int, default=8080, help="the viewer's port (busy: the next free one)")
    view.add_argument("--speed", type=float, default=1.0, help="the run's pace with --view, x real time")


def build_parser() -> argparse.ArgumentParser:
    parser = argparse.ArgumentParser(prog="besman", description=__doc__)
    parser.add_argument("--version", action="version", version=f"besman {__version__}")
    commands = parser.add_subparsers(dest="command", metavar="COMMAND")

    robots = commands.add_parser("robots", help="list, describe and render the robot models")
    robots.set_defaults(handler=_robots_list)
    robot_commands = robots.add_subparsers(dest="robots_command", metavar="ACTION")
    show = robot_commands.add_parser("show", help="joint table of a robot: group, name, limits, speed")
    show.add_argument("name")
    show.add_argument("--json", action="store_true", help="print JSON instead of a table")
    show.set_defaults(handler=_robots_show)
    render = robot_commands.add_parser("render", help="offscreen MuJoCo picture of a robot's scene")
    render.add_argument("name")
    render.add_argument("--out", required=True, help="output PNG file")
    render.add_argument("--width", type=int, default=960)
    render.add_argument("--height", type=int, default=720)
    render.add_argument("--keyframe", default=None, help="keyframe to show (default: home)")
    render.set_defaults(handler=_robots_render)

    tree = commands.add_parser("tree", help="show or render a tree file")
    tree_commands = tree.add_subparsers(dest="tree_command", metavar="ACTION", required=True)
    tree_show = tree_commands.add_parser("show", help="print the tree")
    tree_show.add_argument("file")
    tree_show.set_defaults(handler=_tree_show)
    tree_render = tree_commands.add_parser("render", help="draw the tree with Graphviz")
    tree_render.add_argument("file")
    tree_render.add_argument("--out", required=True, help="output .svg, .png or .dot")
    tree_render.set_defaults(handler=_tree_render)

    run = commands.add_parser("run", help="run a tree file on AILA's tabletop")
    run.add_argument("file")
    run.add_argument(
        "--set",
        action="append",
        default=[],
        metavar="NAME=VALUE[,VALUE]",
        help="object=x,y (where the box stands), place=x,y (where it goes), or any /task value",
    )
    run.add_argument("--seed", type=int, default=None, help="draws object and place when not set")
    run.add_argument("--log", default=None, help="write every tick to this JSON-lines file")
    run.add_argument("--json", action="store_true", help="print the summary as JSON")
    _view_options(run)
    run.set_defaults(handler=_run)

    demo = commands.add_parser("demo", help="grasp-then-place at a default configuration")
    demo.add_argument("--log", default=None, help="write every tick to this JSON-lines file")
    demo.add_argument("--json", action="store_true", help="print the summary as JSON")
    _view_options(demo)
    demo.set_defaults(handler=_demo)

    view = commands.add_parser(
        "view",
        help="in the browser: a run log replayed (scene and tree on a timeline), or a throwing template",
    )
    shown = view.add_mutually_exclusive_group(required=True)
    shown.add_argument("--replay", metavar="LOG", help="a run's JSON-lines log (besman run --log)")
    shown.add_argument(
        "--throw",
        metavar="POOL",
        help="a pool with a throwing template: its spread at the target and the throw of its mean",
    )
    view.add_argument("--template", default="throw", help="the throwing template's name (default: throw)")
    view.add_argument("--target", help="X,Y on the floor (default: the middle of the template's task box)")
    view.add_argument(
        "--host", default="127.0.0.1", help="the viewer's address (default 127.0.0.1: this machine)"
    )
    view.add_argument("--port", type=int, default=8080, help="the viewer's port (busy: the next free one)")
    view.set_defaults(handler=_view)

    tasks = commands.add_parser("tasks", help="the tasks' parameters")
    task_commands = tasks.add_subparsers(dest="tasks_command", metavar="ACTION", required=True)
    task_show = task_commands.add_parser("show", help=f"a task's parameter bounds ({', '.join(TASKS)})")
    task_show.add_argument("name")
    task_show.add_argument("--json", action="store_true")
    task_show.set_defaults(handler=_tasks_show)

    segment = commands.add_parser("segment", help="cut a recording into segments (hand velocity, Bayesian)")
    segment.add_argument("file", help="a recording (.tsv Qualisys export, .csv, .npz)")
    segment.add_argument("--marker", default="Hand top", help="the marker to segment (default: Hand top)")
    segment.add_argument("--json", action="store_true", help="print the segments as JSON")
    inference = segment.add_mutually_exclusive_group()
    inference.add_argument(
        "--exact",
        action="store_true",
        help="exact inference at any length (O(T^2) memory; default up to 60 s)",
    )
    inference.add_argument(
        "--max-particles",
        type=int,
        metavar="N",
        help="pruned inference with N candidate change points (default beyond 60 s: 50)",
    )
    segment.add_argument("--plot", metavar="PNG", help="write the speed with the boundaries to this file")
    segment.add_argument(
        "--examples",
        nargs="+",
        metavar="FILE",
        help="annotated recordings whose segments label the movements found (few-shot, nearest neighbour)",
    )
    segment.add_argument(
        "--example-labels", metavar="L1,L2", help="use only the examples' segments with these labels"
    )
    segment.set_defaults(handler=_segment)

    demos = commands.add_parser("demos", help="inspect recordings")
    demo_commands = demos.add_subparsers(dest="demos_command", metavar="ACTION", required=True)
    demos_show = demo_commands.add_parser("show", help="duration, rate, markers and gaps of a recording")
    demos_show.add_argument("file")
    demos_show.add_argument("--json", action="store_true")
    demos_show.set_defaults(handler=_demos_show)

    pool = commands.add_parser("pool", help="inspect a skill template pool (a directory)")
    pool_commands = pool.add_subparsers(dest="pool_command", metavar="ACTION", required=True)
    pool_ls = pool_commands.add_parser("ls", help="the templates in a pool, one per line")
    pool_ls.add_argument("directory")
    pool_ls.set_defaults(handler=_pool_ls)
    pool_show = pool_commands.add_parser("show", help="one template: task, tau box, training set, kernel")
    pool_show.add_argument("directory")
    pool_show.add_argument("name")
    pool_show.add_argument("--json", action="store_true")
    pool_show.set_defaults(handler=_pool_show)

    experiment = commands.add_parser("experiment", help="the paper's experiments")
    experiment_commands = experiment.add_subparsers(dest="experiment_command", metavar="NAME", required=True)
    throwing = experiment_commands.add_parser(
        "throwing", help="skill templates on PA-10 throwing (Fig. 5): results.json and two plots"
    )
    throwing.add_argument("--quick", action="store_true", help="a small run (3 x 3 grid, K up to 4; minutes)")
    throwing.add_argument("--seeds", type=int, help="independent repetitions (default 3; 1 with --quick)")
    throwing.add_argument("--backend", choices=("threads", "ray"), default="threads")
    throwing.add_argument("--out", required=True, help="the results directory (an interrupted run resumes)")
    throwing.set_defaults(handler=_experiment_throwing)
    return parser


def main(argv: Sequence[str] | None = None) -> int:
    # Offscreen rendering without a screen: EGL unless the user chose otherwise (before `import mujoco`).
    os.environ.setdefault("MUJOCO_GL", "egl")
    parser = build_parser()
    args = parser.parse_args(argv)
    if not hasattr(args, "handler"):
        parser.print_help(sys.stderr)
        return 2
    try:
        return args.handler(args)
    except KeyboardInterrupt:
        print("besman: interrupted (a --log holds the run up to here)", file=sys.stderr)
        return 130
    except (ValueError, KeyError, RuntimeError, OSError) as error:  # TreeFileError is a ValueError
        message = error.args[0] if isinstance(error, KeyError) and error.args else error
        print(f"besman: error: {message}", file=sys.stderr)
        return 2


if __name__ == "__main__":
    sys.exit(main())
