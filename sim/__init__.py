"""Simulation: worlds, tasks, batched rollouts and Ruckig-smoothed execution.

- :mod:`besman.sim.world` - robots composed with furniture and objects (MjSpec); :mod:`besman.sim.objects`
  - graspable objects, the families tasks draw them from and their yaw symmetry.
- :mod:`besman.sim.arm` - the driven joints' limits and kinematic queries (FK, IK, collisions), shared by
  planning and execution.
- :mod:`besman.sim.executor` - runs :mod:`motions <besman.sim.motions>` cycle by cycle through Ruckig
  (:mod:`besman.sim.streaming`), with grasp sensing (:mod:`besman.sim.hand`) and fault checks
  (:mod:`besman.sim.faults`); :mod:`besman.sim.references` turns primitives into joint references.
- :mod:`besman.sim.primitives`, :mod:`besman.sim.manipulation` - movement primitives from goals; pick and
  place planning (:mod:`besman.sim.plans`: a plan's numbers, steps and targets, and
  :mod:`besman.sim.motion_status`: where a motion stands, without MuJoCo).
- :mod:`besman.sim.evaluation` - candidates evaluated in batches (local cores or Ray); the tasks' batched
  rollouts themselves are in :mod:`besman.tasks`.
- :mod:`besman.sim.viewer` - the browser viewer (viser, mjviser): the world posed from the simulation and a
  tree panel; :mod:`besman.sim.serving` - who may open it (its own page only, this machine by default).
"""

from besman.core.lazy import lazy_names

# Where each name lives; imported on first use, so that a light module of the package (its objects) does
# not bring MuJoCo and the executor with it.
_HOMES = {
    "arm": ("Arm",),
    "besman.skills.task_bounds": ("TaskBounds",),
    "evaluation": ("Evaluation",),
    "executor": ("Executor", "ExecutorConfig"),
    "motion_status": ("MotionStatus",),
    "world": ("World", "tabletop_world"),
}


__getattr__, __dir__, __all__ = lazy_names(__name__, _HOMES)
