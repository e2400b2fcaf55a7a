"""besman: robots learn reusable manipulation skills and run them as behaviour trees.

The subpackages follow the BESMAN learning platform (Metzen et al., "Towards Learning of Generic Skills for
Robotic Manipulation", KI 2014): ``besman.skills`` (DMPs and movement primitives), ``besman.learning``
(from demonstrations to primitives), ``besman.robots`` (models and kinematics), ``besman.sim`` (worlds,
rollouts, execution) and ``besman.trees`` (behaviour trees); ``besman.cli`` is the command line on top (its
commands in ``besman.commands``, a module per family).
"""

from besman._version import __version__

__all__ = ["__version__"]
