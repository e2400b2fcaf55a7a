"""besman: robots learn reusable manipulation skills and run them as behaviour trees.

The subpackages follow the BESMAN learning platform (Metzen et al., "Towards Learning of Generic Skills for
Robotic Manipulation", KI 2014): ``besman.skills`` (DMPs and movement primitives), ``besman.learning``
(from demonstrations to primitives), ``besman.robots`` (models and kinematics), ``besman.sim`` (worlds,
rollouts, execution) and ``besman.trees`` (behaviour trees); ``besman.cli`` is the command line on top (its
commands in ``besman.commands``, a module per family).
"""

import os
import signal
import sys
import threading

from besman._version import __version__

__all__ = ["__version__", "main"]


# The signals that stopped the command, in order. SIGTERM (``kill``, a supervisor) raises KeyboardInterrupt as
# Ctrl-C does, so that every clean-up of Ctrl-C runs for it too; which signal it was is kept here, not in the
# exception (Ray's ray.get replaces any KeyboardInterrupt with a new one).
_received: list[int] = []


def main() -> int:
    """The ``besman`` command: the command line (:mod:`besman.cli`), imported here so that a Ctrl-C or a
    SIGTERM while it loads ends with one line too."""
    sys.unraisablehook = _ctrl_c_again(sys.unraisablehook)
    if signal.getsignal(signal.SIGINT) is signal.default_int_handler:  # not where Ctrl-C is ignored
        signal.signal(signal.SIGINT, _stop_after_imports)
    if signal.getsignal(signal.SIGTERM) is signal.SIG_DFL:  # not where SIGTERM is ignored
        signal.signal(signal.SIGTERM, _stop_after_imports)
    try:
        from besman.cli import main as command_line
    except KeyboardInterrupt:  # its modules are pure Python: no extension's ImportError to unwrap
        return stopped()
    code = command_line()
    # The command has ended and said so: a Ctrl-C while the interpreter tears down changes nothing, and a
    # SIGTERM ends it at once (nothing is left to clean up).
    signal.signal(signal.SIGINT, signal.SIG_IGN)
    if signal.getsignal(signal.SIGTERM) is _stop_after_imports:
        signal.signal(signal.SIGTERM, signal.SIG_DFL)
    return code


def stopped(kept: str = "") -> int:
    """Says in one line that Ctrl-C or SIGTERM stopped the command (``kept``: what it leaves that is of use)
    and returns the exit code: 130 for Ctrl-C, 143 for SIGTERM. Both are 128 + the signal's number, what a
    shell reports for a process the signal ended, so a supervisor that sent SIGTERM sees the stop it asked
    for, and not a user's Ctrl-C."""
    terminated = _received[-1:] == [signal.SIGTERM]
    print(f"besman: {'terminated' if terminated else 'interrupted'}{kept}", file=sys.stderr)
    return 143 if terminated else 130


def _stop_after_imports(signum, frame) -> None:
    """Python's Ctrl-C, for SIGTERM too, but not inside an import: a KeyboardInterrupt raised while an
    extension module initialises (mujoco's, numpy's) can leave it half made and crash the process later (a
    segmentation fault, seen once in the suite). Inside an import the signal is sent again 50 ms later, until
    it lands after."""
    while frame is not None:
        if frame.f_code.co_filename.startswith("<frozen importlib"):
            threading.Timer(0.05, os.kill, (os.getpid(), signum)).start()
            return
        frame = frame.f_back
    _received.append(signum)
    raise KeyboardInterrupt


def _ctrl_c_again(report):
    """An unraisable-exception hook that does not lose a Ctrl-C (or a SIGTERM): one that arrives while Python
    runs a callback whose exceptions it only reports (an import lock's weakref callback, a ``__del__``) would
    be printed as "Exception ignored" and the command would run on; it is raised again, where it counts, by
    the signal sent once more from a thread when the callback is over (sent at once, it would land in this
    hook, where exceptions are only reported too)."""

    def hook(unraisable) -> None:
        if unraisable.exc_type is not None and issubclass(unraisable.exc_type, KeyboardInterrupt):
            again = _received[-1] if _received else signal.SIGINT
            threading.Timer(0.05, os.kill, (os.getpid(), again)).start()
            return
        report(unraisable)

    return hook
