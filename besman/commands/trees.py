"""`besman tree`, `besman run` and `besman demo`: tree files shown, drawn, checked and run on their tasks."""

from __future__ import annotations

import argparse
import json
import math
from collections.abc import Sequence
from pathlib import Path

from besman.commands.datasets import check_dataset, dataset_options
from besman.commands.options import SEED
from besman.commands.viewing import check_view, run_task, serve, view_options
from besman.core.errors import InputError


def _drawn_tree(args: argparse.Namespace):
    """The tree of ``args.file`` as ``tree show`` and ``tree render`` draw it: built for ``--robot`` (default:
    the robot of the task the file names), whose pools the paths with ``{robot}`` name, or with ``--pool``."""
    from besman.trees import load_tree
    from besman.trees.files import tree_task

    robot = args.robot
    if robot is not None:
        import besman.robots as robots

        robot = robots.describe(robot).name  # a name, or a robot folder's
    elif Path(args.file).is_file() and (named := tree_task(args.file)) is not None:
        from besman.tasks import task, task_names

        if named in task_names():  # else (a plugin's task, not installed) shown where no pool names {robot}
            robot = task(named).robot
    return load_tree(args.file, pool=args.pool, allow_modules=args.allow_module, robot=robot)


def _tree_show(args: argparse.Namespace) -> int:
    import py_trees

    print(py_trees.display.unicode_tree(_drawn_tree(args)))
    return 0


def _tree_render(args: argparse.Namespace) -> int:
    import py_trees

    from besman.core.storage import check_output, write_atomically

    formats = {".svg": "svg", ".png": "png", ".dot": None}  # .dot: the DOT source itself, no Graphviz
    out = check_output(args.out, option="--out", suffixes=tuple(formats), inputs=(args.file,))
    graph = py_trees.display.dot_tree(_drawn_tree(args))
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


def _parse_sets(pairs: Sequence[str]) -> dict[str, tuple[float, ...] | str | tuple[str, ...]]:
    """``--set NAME=V[,V...]`` as numbers, or as the words given (a choice's name, ``shape=cylinder``): the
    task's value converts and checks them when the run resolves it, so parsing needs no task."""
    values = {}
    for pair in pairs:
        name, equals, text = pair.partition("=")
        if not equals or not name:
            raise InputError(f"--set {pair!r}: expected name=value[,value...]")
        if name in values:
            raise InputError(f"--set {name}: given twice")
        items = [item.strip() for item in text.split(",")]
        try:
            values[name] = tuple(float(item) for item in items)
        except ValueError:
            values[name] = items[0] if len(items) == 1 else tuple(items)
            continue
        if not all(math.isfinite(v) for v in values[name]):
            raise InputError(f"--set {pair!r}: the values must be finite numbers")
    return values


def _words(given) -> bool:
    return isinstance(given, str) or isinstance(given[0], str)


def _check_words(values: dict, task) -> None:
    """Words, before any work: a choice's name for one of ``task``'s values (its own check names what it
    takes); any other value (one the tree reads) takes numbers."""
    known = {value.name: value for value in task.values}
    for name, given in values.items():
        if not _words(given):
            continue
        if name in known:
            known[name].numbers(given)
        else:
            text = given if isinstance(given, str) else ",".join(given)
            raise InputError(
                f"--set {name}={text}: the values must be numbers separated by commas ({name} is not a value "
                f"of task {task.name}, whose values are {', '.join(known) or 'none'})"
            )


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
    from besman.core.storage import check_output, write_atomically
    from besman.tasks import task_names
    from besman.trees.reference import tree_schema

    text = json.dumps(tree_schema(task_names()), indent=2) + "\n"
    if args.out is None:
        print(text, end="")
        return 0
    check_output(args.out, option="--out", suffixes=(".json",))
    write_atomically(args.out, text.encode("utf-8"))
    return 0


def _tree_check(args: argparse.Namespace) -> int:
    from besman.tasks import task_names
    from besman.trees.files import TreeFileError, check_tree

    problems = 0
    for file in args.files:
        try:
            unimported = check_tree(file, allow_modules=args.allow_module, tasks=task_names())
        except TreeFileError as error:
            problems += 1
            print(str(error))
        else:
            later = f" ({', '.join(unimported)}: allowed, imported when the tree runs)" if unimported else ""
            print(f"{file}: ok{later}")
    return 1 if problems else 0


def _perturb_option(parser: argparse.ArgumentParser) -> None:
    parser.add_argument(
        "--perturb",
        choices=("perception", "push"),
        default=None,
        help="perturb the run as the task declares (drawn with --seed): the object's pose perceived with an "
        "error, and with push also pushed while the hand approaches it",
    )


def _run(args: argparse.Namespace) -> int:
    from besman.core.storage import check_output
    from besman.trees.runner import LOG_KIND

    check_view(args)
    check_dataset(args)
    if args.log:
        check_output(args.log, option="--log", suffixes=(".jsonl",), inputs=(args.file,), kind=LOG_KIND)
    values = _parse_sets(args.set)
    if any(_words(given) for given in values.values()):
        from besman.tasks import task
        from besman.trees.files import tree_task

        named = tree_task(args.file)
        if named is not None:  # a file that names no task is refused by the run, as a subtree
            _check_words(values, task(named))
    summary, viewers = run_task(args, tree=args.file, values=values, log=args.log)
    _print_summary(summary, args.json)
    return serve(viewers, 0 if summary.success else 1)


def _demo(args: argparse.Namespace) -> int:
    check_view(args)
    check_dataset(args)
    from besman.tasks import DEFAULT, TASKS, task

    if args.list:
        for entry in TASKS.values():
            if entry.tree is not None:
                print(f"{entry.name}: {entry.title} ({entry.tree}; default robot: {entry.robot})")
        return 0
    chosen = task(args.name or DEFAULT)  # an unknown name is refused with the list, before any work
    if chosen.tree is None:
        demos = ", ".join(name for name, entry in TASKS.items() if entry.tree is not None)
        raise InputError(f"task {chosen.name} has no demo (no default tree); demos: {demos}")
    if args.log:
        from besman.core.storage import check_output
        from besman.trees.runner import LOG_KIND

        check_output(args.log, option="--log", suffixes=(".jsonl",), kind=LOG_KIND)
    values = _parse_sets(args.set)
    _check_words(values, chosen)
    args.robot = chosen.check_robot(args.robot)
    if not args.json:
        print(f"{chosen.name} ({chosen.tree}) on {args.robot}")
    summary, viewers = run_task(args, task=chosen, values=values, log=args.log, demo=chosen.name)
    _print_summary(summary, args.json)
    if not args.json:
        # Another configuration than the one just run; the browser only where it was not just used.
        seed = 1 if args.seed is None else args.seed + 1
        watch = "" if args.view else f"watch it in the browser (besman demo {chosen.name} --view), "
        print(
            f"next: {watch}see the other demos (besman demo --list), or run the same tree as a file, on "
            "another configuration, with a log:\n"
            "  besman examples --copy .\n"
            f"  besman run examples/trees/{chosen.tree} --robot {args.robot} --seed {seed} --log run.jsonl"
        )
    return serve(viewers, 0 if summary.success else 1)


def _allow_module_option(command: argparse.ArgumentParser) -> None:
    command.add_argument(
        "--allow-module",
        action="append",
        default=[],
        metavar="MODULE",
        help="a module whose attributes the tree may name as MODULE:NAME templates and pools (repeatable); "
        "imported when the tree is built, never by tree check",
    )


def _drawn_options(command: argparse.ArgumentParser) -> None:
    """The options of the commands that draw a tree (:func:`_drawn_tree`)."""
    command.add_argument(
        "--robot", default=None, help="build it for this robot (its pools; default: the task's robot)"
    )
    command.add_argument(
        "--pool", default=None, help="a skill template pool that replaces the pools the tree names"
    )
    _allow_module_option(command)


def _set_option(command: argparse.ArgumentParser) -> None:
    command.add_argument(
        "--set",
        action="append",
        default=[],
        metavar="NAME=VALUE[,VALUE]",
        help="a task value, its numbers in the units besman tasks show TASK gives (lengths in m, yaws in "
        "degrees: e.g. object=x,y,yaw), or for a value with choices a name (e.g. shape=cylinder); or any "
        "/task value the tree reads (numbers; repeatable)",
    )


def register(commands) -> None:
    """Adds this module's commands to the parser's subcommands."""
    tree = commands.add_parser("tree", help="show or render a tree file")
    tree_commands = tree.add_subparsers(dest="tree_command", metavar="ACTION", required=True)
    tree_show = tree_commands.add_parser("show", help="print the tree")
    tree_show.add_argument("file")
    _drawn_options(tree_show)
    tree_show.set_defaults(handler=_tree_show)
    tree_render = tree_commands.add_parser("render", help="draw the tree with Graphviz")
    tree_render.add_argument("file")
    tree_render.add_argument("--out", required=True, help="output .svg, .png or .dot")
    _drawn_options(tree_render)
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

    run = commands.add_parser("run", help="run a tree file on the task it names")
    run.add_argument("file")
    run.add_argument(
        "--robot",
        default=None,
        help="a robot's name or folder (besman robots lists them; default: the task's robot)",
    )
    _set_option(run)
    run.add_argument(
        "--seed", type=SEED, default=None, help="draws the task values not set (default: the task's own)"
    )
    _perturb_option(run)
    run.add_argument("--log", default=None, help="write every tick to this JSON-lines file")
    dataset_options(run)
    run.add_argument("--json", action="store_true", help="print the summary as JSON")
    run.add_argument(
        "--pool", default=None, help="a skill template pool that replaces the pools the tree names"
    )
    _allow_module_option(run)
    view_options(run)
    run.set_defaults(handler=_run)

    demo = commands.add_parser(
        "demo", help="run a task's demo, its default tree (besman demo --list; default: the first listed)"
    )
    demo.add_argument("name", nargs="?", default=None, help="the task (default: the first --list lists)")
    demo.add_argument("--list", action="store_true", help="list the demos and exit")
    demo.add_argument("--robot", default=None, help="the robot (default: the task's; besman demo --list)")
    demo.add_argument(
        "--seed", type=SEED, default=None, help="draws the configuration (default: the task's own)"
    )
    _set_option(demo)
    _perturb_option(demo)
    demo.add_argument("--log", default=None, help="write every tick to this JSON-lines file")
    dataset_options(demo)
    demo.add_argument("--json", action="store_true", help="print the summary as JSON")
    view_options(demo)
    demo.set_defaults(handler=_demo)
