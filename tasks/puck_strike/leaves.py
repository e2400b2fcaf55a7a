"""Puck-strike leaves for the UR5e: choose the strike with a skill template over the target, then strike -
the open-loop leaves of :mod:`besman.trees.open_loop`, in the puck strike's roles and words.

- :class:`AimStrike` reads the ``target`` (x, y on the table, m) and instantiates the puck-strike skill
  template there: Theta(tau) is the strike, Omega(tau) the template's uncertainty (Metzen et al. 2014).
  Where the template's own strike would not leave the puck at the target in simulation (the task's rollouts,
  apart from the running simulation), the leaf refines it by CMA-ES started from N(Theta(tau), Omega(tau))
  (population ``population``) until a simulated strike hits or ``budget`` strikes are spent; the template's
  strike and the best are struck once more, and the best is kept only where it gained more than the
  reward's noise (:mod:`~besman.learning.search.acceptance`). It writes the strike's parameters (role
  ``strike``); a target outside the template's box fails it, with a message that names it.
- :class:`Strike` executes the strike in the running simulation
  (:class:`~besman.sim.open_loop_executor.OpenLoopExecutor`), RUNNING while the arm strikes and the puck
  slides, and writes where the puck came to rest (role ``puck``: x, y in m, the rollouts' rest point); it
  succeeds if the puck is at rest on the table within 0.05 m of the target (the task's rule).

Blackboard keys: ``/<ns>/strike``, the strike for ``/<ns>/target`` (the instantiated, possibly refined,
template), ``AimStrike`` writes and ``Strike`` reads; ``/<ns>/puck``, where the puck came to rest, ``Strike``
writes. Both are node types as any distribution's are (:data:`NODE_TYPES`, named under the entry-point group
``besman.node_types`` in besman's own ``pyproject.toml``).
"""

from __future__ import annotations

from typing import TYPE_CHECKING, ClassVar

import numpy as np
from py_trees.common import Access

from besman.trees.open_loop import OpenLoopAim, OpenLoopRun

if TYPE_CHECKING:
    from besman.sim.open_loop_executor import OpenLoopMotion


class AimStrike(OpenLoopAim):
    """Instantiates the template ``template`` of ``pool`` for the ``target`` and refines it in simulation
    where the puck would not come to rest on it, with at most ``budget`` more simulated strikes; writes
    ``strike``."""

    roles: ClassVar = {"target": Access.READ, "strike": Access.WRITE}
    default_template: ClassVar = "puck_strike"
    demo: ClassVar = "puck-strike"
    motions: ClassVar = "strikes"
    succeeds: ClassVar = "hits"
    fails: ClassVar = "misses"


class Strike(OpenLoopRun):
    """Strikes ``strike`` and writes where the ``puck`` came to rest (x, y); succeeds if it rests on the
    target."""

    roles: ClassVar = {"strike": Access.READ, "puck": Access.WRITE}
    demo: ClassVar = "puck-strike"
    doing: ClassVar = "striking"

    def outcome(self, motion: OpenLoopMotion) -> tuple[np.ndarray, str]:
        detail = motion.detail
        puck = np.round(detail.rest, 3)
        return puck, f"the puck came to rest at {puck.tolist()}, {detail.distance:.3f} m from the target"


NODE_TYPES = (AimStrike, Strike)  # registered by besman.trees.nodes (its entry points)
