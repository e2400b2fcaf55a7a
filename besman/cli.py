"""besman: robots learn reusable manipulation skills and run them as behaviour trees (the command line).

The parser, its error handling and the commands' modules (:mod:`besman.commands`): each module registers its
commands and holds their handlers, which import what they use only when they run (``besman --help`` stays
fast).
"""

from __future__ import annotations

import argparse
import os
import sys
from collections.abc import Sequence

from besman._version import __version__
from besman.commands import learning, pool, recordings, robots, tasks, trees, viewing


def build_parser() -> argparse.ArgumentParser:
    parser = argparse.ArgumentParser(prog="besman", description=__doc__.splitlines()[0])
    parser.add_argument("--version", action="version", version=f"besman {__version__}")
    commands = parser.add_subparsers(dest="command", metavar="COMMAND")
    for module in (robots, trees, viewing, tasks, recordings, learning, pool):
        module.register(commands)
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
        resumes = args.command in ("learn", "experiment")  # their outputs keep each finished stage
        note = "run it again to resume" if resumes else "a --log holds the run up to here"
        print(f"besman: interrupted ({note})", file=sys.stderr)
        return 130
    except (ValueError, KeyError, RuntimeError, OSError) as error:  # TreeFileError is a ValueError
        message = error.args[0] if isinstance(error, KeyError) and error.args else error
        print(f"besman: error: {message}", file=sys.stderr)
        return 2


if __name__ == "__main__":
    sys.exit(main())
