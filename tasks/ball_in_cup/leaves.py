"""Ball-in-a-cup leaves for the UR5e: choose the swing with a skill template over the string's length, then
swing - the open-loop leaves of :mod:`besman.trees.open_loop`, in the ball-in-a-cup's roles and words.

- :class:`AimSwing` reads the string's length (``string``, m) and instantiates the ball-in-a-cup skill
  template there: Theta(tau) is the swing, Omega(tau) the template's uncertainty (Metzen et al. 2014). Where
  the template's own swing would not catch the ball in simulation (the task's rollouts, apart from the
  running simulation), the leaf refines it by CMA-ES started from N(Theta(tau), Omega(tau)) (population
  ``population``) until a simulated swing catches or ``budget`` swings are spent; the template's swing and
  the best are swung once more, and the best is kept only where it gained more than the reward's noise
  (:mod:`~besman.learning.search.acceptance`). It writes the swing's parameters (role ``swing``).
- :class:`Swing` executes the swing in the running simulation
  (:class:`~besman.sim.open_loop_executor.OpenLoopExecutor`), RUNNING while the arm swings and the ball flies
  and settles, and writes where the ball ended in the cup's frame (role ``ball``); it succeeds if the ball is
  inside the cup for the swing's last 0.25 s (the task's rule).

Blackboard keys: ``/<ns>/swing``, the swing for ``/<ns>/string`` (the instantiated, possibly refined,
template), ``AimSwing`` writes and ``Swing`` reads; ``/<ns>/ball``, the ball's centre at the end (x, y, z in
the cup's frame), ``Swing`` writes. Both are node types as any distribution's are (:data:`NODE_TYPES`, named
under the entry-point group ``besman.node_types`` in besman's own ``pyproject.toml``).
"""

from __future__ import annotations

from typing import TYPE_CHECKING, ClassVar

import numpy as np
from py_trees.common import Access

from besman.trees.open_loop import OpenLoopAim, OpenLoopRun

if TYPE_CHECKING:
    from besman.sim.open_loop_executor import OpenLoopMotion


class AimSwing(OpenLoopAim):
    """Instantiates the template ``template`` of ``pool`` for the ``string`` length and refines it in
    simulation where it would not catch, with at most ``budget`` more simulated swings; writes ``swing``."""

    roles: ClassVar = {"string": Access.READ, "swing": Access.WRITE}
    default_template: ClassVar = "ball_in_cup"
    demo: ClassVar = "ball-in-cup"
    motions: ClassVar = "swings"
    succeeds: ClassVar = "catches"
    fails: ClassVar = "misses"


class Swing(OpenLoopRun):
    """Swings ``swing`` and writes where the ``ball`` ended (cup frame); succeeds if it was caught."""

    roles: ClassVar = {"swing": Access.READ, "ball": Access.WRITE}
    demo: ClassVar = "ball-in-cup"
    doing: ClassVar = "swinging"

    def outcome(self, motion: OpenLoopMotion) -> tuple[np.ndarray, str]:
        sensor = self.executor.world.model.sensor("ball_in_cup").adr[0]
        ball = np.round(motion.last_sensors[sensor : sensor + 3], 3)
        caught = "in" if motion.detail.success else "not in"
        return ball, f"the ball is {caught} the cup, at {ball.tolist()} (cup frame)"


NODE_TYPES = (AimSwing, Swing)  # registered by besman.trees.nodes (its entry points)
