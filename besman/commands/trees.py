"""`besman tree`, `besman run` and `besman demo`: tree files shown, drawn and run on AILA's tabletop."""

from __future__ import annotations

import argparse
import json
import math
import sys
from collections.abc import Sequence
from dataclasses import replace
from pathlib import Path

from besman.commands.options import SEED
from besman.commands.viewing import check_view, serve, server_settings, tabletop, view_options
from besman.skills.errors import InputError


def _tree_show(args: argparse.Namespace) -> int:
    import py_trees

    from besman.trees import load_tree

    print(py_trees.display.unicode_tree(load_tree(args.file, allow_modules=args.allow_module)))
    return 0


def _tree_render(args: argparse.Namespace) -> int:
    import py_trees

    from besman.skills.storage import check_output, write_atomically
    from besman.trees import load_tree

    formats = {".svg": "svg", ".png": "png", ".dot": None}  # .dot: the DOT source itself, no Graphviz
    out = check_output(args.out, option="--out", suffixes=tuple(formats), inputs=(args.file,))
    graph = py_trees.display.dot_tree(load_tree(args.file, allow_modules=args.allow_module))
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


def _print_summary(summary, as_json: bool) -> None:
    """A run's :class:`~besman.trees.summary.RunSummary`, as JSON or as its lines for people."""
    print(json.dumps(summary.to_json(), indent=2) if as_json else summary.text())


def _tree_nodes(args: argparse.Namespace) -> int:
    from besman.trees.reference import markdown_reference, node_reference

    if args.markdown:
        print(markdown_reference())
        return 0
    reference = node_reference(args.name)
    if args.json:
        print(json.dumps(reference, indent=2))
        return 0
    for type_name, entry in reference.items():
        print(f"{type_name}: {entry['description']}")
        if args.name is None:
            continue
        for param_name, param in entry["parameters"].items():
            facts = [param["kind"], "required" if param["required"] else f"default {param['default']!r}"]
            print(f"  {param_name}: " + ", ".join(facts + ([param["range"]] if param["range"] else [])))
        for role, access in entry["blackboard"].items():
            print(f"  blackboard {role}: {access}")
    return 0


def _tree_schema(args: argparse.Namespace) -> int:
    from besman.skills.storage import check_output, write_atomically
    from besman.trees.reference import tree_schema

    text = json.dumps(tree_schema(), indent=2) + "\n"
    if args.out is None:
        print(text, end="")
        return 0
    check_output(args.out, option="--out", suffixes=(".json",))
    write_atomically(args.out, text.encode("utf-8"))
    return 0


def _tree_check(args: argparse.Namespace) -> int:
    from besman.trees import check_tree
    from besman.trees.files import TreeFileError

    problems = 0
    for file in args.files:
        try:
            unimported = check_tree(file, allow_modules=args.allow_module)
        except TreeFileError as error:
            problems += 1
            print(str(error))
        else:
            later = f" ({', '.join(unimported)}: allowed, imported when the tree runs)" if unimported else ""
            print(f"{file}: ok{later}")
    return 1 if problems else 0


def _run(args: argparse.Namespace) -> int:
    from besman.skills.storage import check_output
    from besman.trees.runner import LOG_KIND

    check_view(args)
    if args.log:
        check_output(args.log, option="--log", suffixes=(".jsonl",), inputs=(args.file,), kind=LOG_KIND)
    tree = args.file
    if args.pool is not None or args.allow_module:  # pools replaced, modules imported: logged as built
        from besman.trees import load_tree

        tree = load_tree(args.file, pool=args.pool, allow_modules=args.allow_module)
    summary, viewers = tabletop(args, tree, _parse_sets(args.set), args.log)
    if tree is not args.file:
        replaced = f" (--pool {Path(args.pool).resolve()})" if args.pool is not None else ""
        summary = replace(summary, tree=f"{Path(args.file).resolve()}{replaced}")
    _print_summary(summary, args.json)
    return serve(viewers, 0 if summary.success else 1)


def _demo(args: argparse.Namespace) -> int:
    check_view(args)
    from besman.skills.storage import check_output
    from besman.trees.gallery import DEMOS, demo
    from besman.trees.runner import LOG_KIND

    if args.list:
        for entry in DEMOS.values():
            print(f"{entry.name}: {entry.title} ({entry.path.name})")
        return 0
    chosen = demo(args.name)  # an unknown name is refused with the list, before any work
    if args.log:
        check_output(args.log, option="--log", suffixes=(".jsonl",), kind=LOG_KIND)
    args.robot = chosen.check_robot(args.robot)
    options = {"robot": args.robot}
    if args.target is not None:
        if chosen.name != "throw":
            raise InputError(f"--target is for the throw demo, not {chosen.name}")
        options["target"] = _parse_sets([f"target={args.target}"])["target"]
    if not args.json:
        print(f"{chosen.name} ({chosen.path.name}) on {args.robot}")
    summary, viewers = _watched_demo(args, chosen, options)
    _print_summary(summary, args.json)
    if not args.json and chosen.name == "grasp-then-place":
        elsewhere = (  # a configuration of the robot's own tabletop: AILA's below, any robot's by a seed
            "--set object=0.5,-0.05 --set place=0.58,-0.44"
            if args.robot == "aila"
            else f"--robot {args.robot} --seed 1"
        )
        print(
            "next: watch it in the browser (besman demo --view), see the other demos (besman demo --list), "
            "or run the same tree as a file elsewhere on the table with a log:\n"
            "  besman examples --copy .\n"
            f"  besman run examples/trees/grasp_then_place.yaml {elsewhere} --log run.jsonl"
        )
    return serve(viewers, 0 if summary.success else 1)


def _watched_demo(args: argparse.Namespace, chosen, options: dict) -> tuple:
    """Runs a gallery demo; with --view, watched in the browser at --speed (the viewer stays open).
    Grasp-then-place is watched in a session (Run, Pause, Step, breakpoints, the box and place dragged)."""
    from besman.trees.gallery import grasp_then_place_values, run_demo

    if chosen.name == "grasp-then-place":
        values = grasp_then_place_values(args.robot, args.seed)
        summary, viewers = tabletop(args, str(chosen.path), values, args.log)
        return replace(summary, demo=chosen.name), viewers
    if not args.view:
        return run_demo(chosen.name, args.seed, options, log=args.log), []
    from besman.sim.viewer import Viewer
    from besman.trees.gallery import observers, prepare_demo
    from besman.trees.watching import Watch

    prepared = prepare_demo(chosen.name, args.seed, options)
    viewer = Viewer(prepared.runner.executor.world.model, **server_settings(args))
    print(f"viewer: {viewer.url} (the run goes at {args.speed:g}x real time)", file=sys.stderr, flush=True)
    prepared.runner.observe = observers(prepared.runner.observe, Watch(viewer, args.speed))
    try:
        result = prepared.runner.run(log=args.log)
    except BaseException:
        viewer.close()
        raise
    return prepared.judge(result), [viewer]


def _allow_module_option(command: argparse.ArgumentParser) -> None:
    command.add_argument(
        "--allow-module",
        action="append",
        default=[],
        metavar="MODULE",
        help="a module whose attributes the tree may name as MODULE:NAME templates and pools (repeatable); "
        "imported when the tree is built, never by tree check",
    )


def register(commands) -> None:
    """Adds this module's commands to the parser's subcommands."""
    tree = commands.add_parser("tree", help="show or render a tree file")
    tree_commands = tree.add_subparsers(dest="tree_command", metavar="ACTION", required=True)
    tree_show = tree_commands.add_parser("show", help="print the tree")
    tree_show.add_argument("file")
    _allow_module_option(tree_show)
    tree_show.set_defaults(handler=_tree_show)
    tree_render = tree_commands.add_parser("render", help="draw the tree with Graphviz")
    tree_render.add_argument("file")
    tree_render.add_argument("--out", required=True, help="output .svg, .png or .dot")
    _allow_module_option(tree_render)
    tree_render.set_defaults(handler=_tree_render)
    tree_nodes = tree_commands.add_parser("nodes", help="the node types of tree files and their parameters")
    tree_nodes.add_argument("name", nargs="?", help="one node type, with its parameters and blackboard roles")
    shown = tree_nodes.add_mutually_exclusive_group()
    shown.add_argument("--json", action="store_true", help="everything as JSON")
    shown.add_argument("--markdown", action="store_true", help="the reference as Markdown (docs/trees.md)")
    tree_nodes.set_defaults(handler=_tree_nodes)
    tree_schema = tree_commands.add_parser("schema", help="the JSON Schema of tree files, for editors")
    tree_schema.add_argument("--out", default=None, help="write it to this .json file instead of printing it")
    tree_schema.set_defaults(handler=_tree_schema)
    tree_check = tree_commands.add_parser("check", help="load and validate tree files; one line per file")
    tree_check.add_argument("files", nargs="+", metavar="FILE")
    _allow_module_option(tree_check)
    tree_check.set_defaults(handler=_tree_check)

    run = commands.add_parser("run", help="run a tree file on a robot's tabletop (default: AILA's)")
    run.add_argument("file")
    run.add_argument(
        "--robot", default="aila", help="a robot's name or folder (besman robots lists them; default: aila)"
    )
    run.add_argument(
        "--set",
        action="append",
        default=[],
        metavar="NAME=VALUE[,VALUE]",
        help="object=x,y (where the box stands), place=x,y (where it goes), or any /task value",
    )
    run.add_argument("--seed", type=SEED, default=None, help="draws object and place when not set")
    run.add_argument("--log", default=None, help="write every tick to this JSON-lines file")
    run.add_argument("--json", action="store_true", help="print the summary as JSON")
    run.add_argument(
        "--pool", default=None, help="a skill template pool that replaces the pools the tree names"
    )
    _allow_module_option(run)
    view_options(run)
    run.set_defaults(handler=_run)

    demo = commands.add_parser(
        "demo", help="run a demo of the gallery (besman demo --list); default: grasp-then-place"
    )
    demo.add_argument(
        "name", nargs="?", default="grasp-then-place", help="the demo (default: grasp-then-place)"
    )
    demo.add_argument("--list", action="store_true", help="list the demos and exit")
    demo.add_argument("--robot", default=None, help="the robot (default: the demo's; besman demo --list)")
    demo.add_argument(
        "--seed", type=SEED, default=None, help="draws the demo's configuration (default: a fixed one)"
    )
    demo.add_argument(
        "--target", default=None, metavar="X,Y", help="where the throw demo aims (m on the floor)"
    )
    demo.add_argument("--log", default=None, help="write every tick to this JSON-lines file")
    demo.add_argument("--json", action="store_true", help="print the summary as JSON")
    view_options(demo)
    demo.set_defaults(handler=_demo)
