"""`besman tree`, `besman run` and `besman demo`: tree files shown, drawn and run on AILA's tabletop."""

from __future__ import annotations

import argparse
import json
import math
from collections.abc import Sequence

from besman.commands.viewing import serve, tabletop, view_options
from besman.skills.errors import InputError
from besman.skills.storage import check_output


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


def _run(args: argparse.Namespace) -> int:

    if args.log:
        check_output(args.log, option="--log", suffixes=(".jsonl",), inputs=(args.file,))
    tree = args.file
    if args.pool is not None:  # the file's pools replaced: the tree is built here and logged as built
        from besman.trees import load_tree

        tree = load_tree(args.file, pool=args.pool)
    summary, viewers = tabletop(args, tree, _parse_sets(args.set), args.log)
    _print_summary(summary, args.json)
    return serve(viewers, 0 if summary["status"] == "SUCCESS" else 1)


def _demo(args: argparse.Namespace) -> int:
    from besman.trees import grasp_then_place

    if args.log:
        check_output(args.log, option="--log", suffixes=(".jsonl",))
    if not args.json:  # --json prints the summary alone
        print("AILA grasps the box on the table and places it on the shelf (grasp-then-place tree)")
    summary, viewers = tabletop(
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
    return serve(viewers, 0 if summary["status"] == "SUCCESS" else 1)


def register(commands) -> None:
    """Adds this module's commands to the parser's subcommands."""
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
    run.add_argument(
        "--pool", default=None, help="a skill template pool that replaces the pools the tree names"
    )
    view_options(run)
    run.set_defaults(handler=_run)

    demo = commands.add_parser("demo", help="grasp-then-place at a default configuration")
    demo.add_argument("--log", default=None, help="write every tick to this JSON-lines file")
    demo.add_argument("--json", action="store_true", help="print the summary as JSON")
    view_options(demo)
    demo.set_defaults(handler=_demo)
