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


def main() -> int:
    """The ``besman`` command: the command line (:mod:`besman.cli`), imported here so that a Ctrl-C while
    it loads ends with one line too."""
    sys.unraisablehook = _ctrl_c_again(sys.unraisablehook)
    if signal.getsignal(signal.SIGINT) is signal.default_int_handler:  # not where Ctrl-C is ignored
        signal.signal(signal.SIGINT, _ctrl_c_after_imports)
    try:
        from besman.cli import main as command_line
    except KeyboardInterrupt:  # its modules are pure Python: no extension's ImportError to unwrap
        print("besman: interrupted", file=sys.stderr)
        return 130
    code = command_line()
    # The command has ended and said so: a Ctrl-C while the interpreter tears down changes nothing.
    signal.signal(signal.SIGINT, signal.SIG_IGN)
    return code


def _ctrl_c_after_imports(signum, frame) -> None:
    """Python's Ctrl-C, but not inside an import: a KeyboardInterrupt raised while an extension module
    initialises (mujoco's, numpy's) can leave it half made and crash the process later (a segmentation
    fault, seen once in the suite). Inside an import it is sent again 50 ms later, until it lands after."""
    while frame is not None:
        if frame.f_code.co_filename.startswith("<frozen importlib"):
            threading.Timer(0.05, os.kill, (os.getpid(), signal.SIGINT)).start()
            return
        frame = frame.f_back
    raise KeyboardInterrupt


def _ctrl_c_again(report):
    """An unraisable-exception hook that does not lose a Ctrl-C: one that arrives while Python runs a
    callback whose exceptions it only reports (an import lock's weakref callback, a ``__del__``) would be
    printed as "Exception ignored" and the command would run on; it is raised again, where it counts, by
    SIGINT sent once more from a thread when the callback is over (sent at once, it would land in this hook,
    where exceptions are only reported too)."""

    def hook(unraisable) -> None:
        if unraisable.exc_type is not None and issubclass(unraisable.exc_type, KeyboardInterrupt):
            threading.Timer(0.05, os.kill, (os.getpid(), signal.SIGINT)).start()
            return
        report(unraisable)

    return hook
