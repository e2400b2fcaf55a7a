"""The browser viewer from the command line: `--view` for runs (a session that stays open after the run)
and `besman view` (a run log replayed, a throwing template). The viewer serves this machine alone unless
``--host`` says otherwise (then with a warning), and its websocket answers only its own page and the
``--allow-origin`` pages (:mod:`besman.sim.serving`).
"""

from __future__ import annotations

import argparse
import sys
import time

from besman.commands.options import PORT, positive
from besman.core.errors import InputError
from besman.stopping import stopped


def server_options(group) -> None:
    """--host, --port and --allow-origin: where the viewer serves and which pages may use it."""
    group.add_argument(
        "--host",
        default="127.0.0.1",
        help="the viewer's address (default 127.0.0.1: this machine alone); another, e.g. 0.0.0.0 (every "
        "address of this machine), serves the network with no authentication: a warning says so",
    )
    group.add_argument("--port", type=PORT, default=8080, help="the viewer's port (busy: the next free one)")
    group.add_argument(
        "--allow-origin",
        action="append",
        default=[],
        metavar="URL",
        help="a page that may use the viewer besides its own, e.g. https://viewer.example.org for a proxy in "
        "front of it (repeatable); websockets from any other page are refused",
    )


def server_settings(args: argparse.Namespace) -> dict:
    """The viewer's keyword arguments from :func:`server_options`, checked (an address that is not this
    machine's, an origin that is none, fails at once, in one line)."""
    from besman.sim.hosts import host_addresses, origins  # here: parsing a command loads no simulation

    host_addresses(args.host)
    origins(args.allow_origin)
    return {"host": args.host, "port": args.port, "allowed_origins": args.allow_origin}


def check_view(args: argparse.Namespace) -> None:
    """With --view, the viewer's host checked before any work."""
    if args.view:
        server_settings(args)


def view_options(command: argparse.ArgumentParser) -> None:
    """The options of a command that runs a tree to watch it in the browser (``--view``)."""
    view = command.add_argument_group("browser viewer")
    view.add_argument("--view", action="store_true", help="watch the run in the browser (viser)")
    server_options(view)
    view.add_argument("--speed", type=positive, default=1.0, help="the run's pace with --view, x real time")


def run_task(args: argparse.Namespace, *, task=None, tree=None, values: dict, log, demo=None) -> tuple:
    """Runs ``tree`` (default: the task's) on ``task`` (default: the one the tree file names) as the
    command line asks (``--robot``, ``--seed``, ``--pool``, ``--allow-module``); with --dataset appended to
    it as an episode; with --view inside a browser session that stays open after the run (returned in the
    list, for :func:`serve`)."""
    options = {
        "robot": args.robot,
        "seed": getattr(args, "seed", None),
        "pool": getattr(args, "pool", None),
        "allow_modules": getattr(args, "allow_module", ()),
        "demo": demo,
        "perturb": getattr(args, "perturb", None),
    }
    if getattr(args, "dataset", None):  # --view refused before (check_dataset)
        from besman.tasks.recording import record_run

        summary, index = record_run(
            task, tree, dataset=args.dataset, video=args.video, values=values, log=log, **options
        )
        print(f"{args.dataset}: the run is episode {index}", file=sys.stderr)
        return summary, []
    if not args.view:
        from besman.commands.progress import RunProgress
        from besman.tasks.running import run

        with RunProgress() as progress:
            return run(task, tree, values=values, log=log, observe=progress.observe, **options), []
    from besman.tasks.session import Session

    session = Session(
        tree if tree is not None else task.tree_path,
        values,
        task=None if task is None else task.name,
        speed=args.speed,
        viewer_options=server_settings(args),
        **options,
    )
    print(
        f"viewer: {session.viewer.url} (the run starts now, at {args.speed:g}x real time; opened later, the "
        "page's Reset, then Run, runs it again from the start)",
        file=sys.stderr,
        flush=True,
    )
    try:
        result = session.start(log=log)
    except BaseException:
        session.close()
        raise
    return session.judge(result), [session]


def serve(viewers: list, code: int) -> int:
    """Keeps a viewer (anything with ``url`` and ``close()``) open until Ctrl-C or SIGTERM, which end it as
    they end every command: the viewer closed, one line (``besman: interrupted`` or ``besman: terminated``)
    and exit 130 or 143 (:func:`besman.stopping.stopped`). ``code``, the command's own, is returned when there
    is no viewer to serve."""
    if not viewers:
        return code
    print(f"the viewer stays at {viewers[0].url} until Ctrl-C", file=sys.stderr, flush=True)
    try:
        while True:
            time.sleep(3600)
    except KeyboardInterrupt:  # Ctrl-C, or SIGTERM (besman.main)
        viewers[0].close()
        return stopped()


def _view(args: argparse.Namespace) -> int:
    options = server_settings(args)
    if args.throw:
        return _view_throw(args, options)
    from besman.tasks.running import executor_of
    from besman.trees.watching import Replay

    replay = Replay(args.replay, executor_of, options)
    print(
        f"replay of {args.replay} ({len(replay.records)} ticks): {replay.viewer.url}",
        file=sys.stderr,
        flush=True,
    )
    return serve([replay], 0)


def _view_throw(args: argparse.Namespace, options: dict) -> int:
    from besman.skills.pool import SkillTemplatePool
    from besman.tasks.throwing.view import ThrowingView

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
    return serve([view], 0)


def register(commands) -> None:
    """Adds this module's commands to the parser's subcommands."""
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
    server_options(view)
    view.set_defaults(handler=_view)
