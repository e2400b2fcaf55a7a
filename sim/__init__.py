"""Simulation: worlds, tasks, batched rollouts and Ruckig-smoothed execution.

- :mod:`besman.sim.world` - robots composed with furniture and objects (MjSpec).
- :mod:`besman.sim.executor` - every commanded motion through Ruckig, grasps, faults.
- :mod:`besman.sim.primitives`, :mod:`besman.sim.manipulation` - movement primitives from goals; pick and
  place planning.
- :mod:`besman.sim.throwing`, :mod:`besman.sim.pick_place` - the tasks, evaluated in batches
  (:mod:`besman.sim.evaluation`: local cores or Ray).
"""

from besman.sim.evaluation import Evaluation
from besman.sim.executor import Executor, ExecutorConfig, MotionStatus
from besman.sim.pick_place import PickPlaceTask
from besman.sim.tasks import TaskBounds
from besman.sim.throwing import ThrowingConfig, ThrowingTask
from besman.sim.world import World, tabletop_world, throwing_world

__all__ = [
    "Evaluation",
    "Executor",
    "ExecutorConfig",
    "MotionStatus",
    "PickPlaceTask",
    "TaskBounds",
    "ThrowingConfig",
    "ThrowingTask",
    "World",
    "tabletop_world",
    "throwing_world",
]
