"""besman: robots learn reusable manipulation skills and run them as behaviour trees (the command line).

The parser, its error handling and the commands' modules (:mod:`besman.commands`): each module registers its
commands and holds their handlers, which import what they use only when they run (``besman --help`` stays
fast).
"""

from __future__ import annotations

import argparse
import os
import select
import sys
import time
import warnings
from collections.abc import Iterator, Sequence

from besman._version import __version__
from besman.commands import datasets, examples, learning, pool, recordings, robots, tasks, trees, viewing
from besman.core.errors import PluginWarning
from besman.stopping import PIPE_CLOSED, stopped


def build_parser() -> argparse.ArgumentParser:
    parser = argparse.ArgumentParser(prog="besman", description=__doc__.splitlines()[0])
    parser.add_argument("--version", action="version", version=f"besman {__version__}")
    commands = parser.add_subparsers(dest="command", metavar="COMMAND")
    for module in (robots, trees, viewing, tasks, recordings, datasets, learning, pool, examples):
        module.register(commands)
    return parser


def commands(
    parser: argparse.ArgumentParser, path: tuple[str, ...] = ()
) -> Iterator[tuple[tuple[str, ...], argparse.ArgumentParser]]:
    """Every command and subcommand of ``parser`` (itself first) with its path of names."""
    yield path, parser
    for action in parser._actions:
        if isinstance(action, argparse._SubParsersAction):
            for name, command in action.choices.items():
                yield from commands(command, (*path, name))


def main(argv: Sequence[str] | None = None) -> int:
    started = time.time()
    args = None
    try:
        # Offscreen rendering without a screen: EGL unless the user chose otherwise (before `import mujoco`).
        os.environ.setdefault("MUJOCO_GL", "egl")
        parser = build_parser()
        args = parser.parse_args(respelled(sys.argv[1:] if argv is None else list(argv)))
        if not hasattr(args, "handler"):
            parser.print_help(sys.stderr)
            return 2
        with warnings.catch_warnings():  # restores Python's display after (main runs many times in tests)
            warnings.showwarning = _one_line(warnings.showwarning)
            return args.handler(args)
    except KeyboardInterrupt:  # Ctrl-C, or SIGTERM (besman.main)
        return stopped(_kept(args, started))
    except ImportError as error:
        if not interrupted(error):
            raise
        return stopped(_kept(args, started))
    except BrokenPipeError as error:
        if not _reader_gone():  # a pipe of the command's own (a worker's, a socket): a failure to report
            print(f"besman: error: {error}", file=sys.stderr)
            return 2
        # The reader of the output stopped reading (besman tree nodes | head): the rest is not wanted.
        os.dup2(os.open(os.devnull, os.O_WRONLY), sys.stdout.fileno())  # what is left to flush goes nowhere
        return PIPE_CLOSED
    except (ValueError, KeyError, RuntimeError, OSError) as error:  # TreeFileError is a ValueError
        message = error.args[0] if isinstance(error, KeyError) and error.args else error
        print(f"besman: error: {message}", file=sys.stderr)
        return 2


def _reader_gone() -> bool:
    """Whether standard output is a pipe whose reader has closed it (poll reports an error on its end)."""
    try:
        descriptor = sys.stdout.fileno()
    except (OSError, ValueError):  # not a file (output captured in the process)
        return False
    poller = select.poll()
    poller.register(descriptor, select.POLLOUT)
    return any(events & select.POLLERR for _, events in poller.poll(0))


# Spellings of the previous release that keep working for this one, with a warning: (command, old) -> new;
# the command "" is the first word itself.
OLD_SPELLINGS = {("", "demos"): "recordings", ("learn", "--tasks"): "--training-tasks"}


def respelled(argv: list[str]) -> list[str]:
    """``argv`` with the previous release's spellings (:data:`OLD_SPELLINGS`) in this one's, each warned of in
    one line."""
    argv = list(argv)
    command = next((i for i, word in enumerate(argv) if not word.startswith("-")), None)
    if command is None:
        return argv
    for index, word in enumerate(argv):
        name, equals, value = word.partition("=")
        key = ("", name) if index == command else (argv[command], name)
        if key in OLD_SPELLINGS and (index == command or (index > command and name.startswith("--"))):
            new = OLD_SPELLINGS[key]
            said = f"besman {name}" if index == command else f"besman {argv[command]} {name}"
            print(
                f"besman: warning: {said} is now {new} (the old spelling goes in the next release)",
                file=sys.stderr,
            )
            argv[index] = new + equals + value
    return argv


def _one_line(show):
    """Python's warning display, but a besman plugin's warning as one line like its errors (without the
    file and source line of the code that warned: the message names the plugin)."""

    def display(message, category, filename, lineno, file=None, line=None):
        if issubclass(category, PluginWarning):
            print(f"besman: warning: {message}", file=sys.stderr if file is None else file)
        else:
            show(message, category, filename, lineno, file, line)

    return display


def interrupted(error: BaseException) -> bool:
    """Whether ``error`` comes of a Ctrl-C: an extension module whose initialisation a KeyboardInterrupt
    stopped raises an ImportError caused by it."""
    cause = error.__cause__ or error.__context__
    return isinstance(cause, KeyboardInterrupt) or (cause is not None and interrupted(cause))


def _kept(args: argparse.Namespace | None, started: float) -> str:
    """What an interrupted command leaves that is of use, for its one line."""
    command = getattr(args, "command", None)
    if command in ("learn", "experiment", "record"):  # their outputs keep each finished stage (episode)
        return " (run it again to resume)"
    log = getattr(args, "log", None)
    if log and os.path.exists(log) and os.path.getmtime(log) >= started:
        return f" ({log} holds the run up to here)"
    return ""


if __name__ == "__main__":
    sys.exit(main())
