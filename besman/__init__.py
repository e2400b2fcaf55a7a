"""besman: robots learn reusable manipulation skills and run them as behaviour trees.

The subpackages follow the BESMAN learning platform (Metzen et al., "Towards Learning of Generic Skills for
Robotic Manipulation", KI 2014): ``besman.skills`` (DMPs and movement primitives), ``besman.learning``
(from demonstrations to primitives), ``besman.robots`` (models and kinematics), ``besman.sim`` (worlds,
rollouts, execution) and ``besman.trees`` (behaviour trees); ``besman.cli`` is the command line on top (its
commands in ``besman.commands``, a module per family).
"""

import sys

from besman._version import __version__

__all__ = ["__version__", "main"]


def main() -> int:
    """The ``besman`` command: the command line (:mod:`besman.cli`), imported here so that a Ctrl-C while
    it loads ends with one line too."""
    try:
        from besman.cli import main as command_line
    except KeyboardInterrupt:
        print("besman: interrupted", file=sys.stderr)
        return 130
    return command_line()
