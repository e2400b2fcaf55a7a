"""Puck strike: the UR5e strikes a puck with the bat it holds so that the puck slides across the table to a
target beyond the arm's reach - a non-prehensile, dynamic skill: :mod:`besman.tasks.puck_strike.rollouts`
(the batched rollouts of policy search), :mod:`~besman.tasks.puck_strike.world` (the long table, the puck
and the bat in MuJoCo), :mod:`~besman.tasks.puck_strike.demonstration` (a synthetic demonstration that
misses, and its imitation) and :mod:`~besman.tasks.puck_strike.baseline` (the best hand-written strike).

The run starts with the arm at rest in :data:`~besman.tasks.puck_strike.rollouts.START` (the bat drawn back
behind the puck), the puck (an ice-hockey puck's size and mass: 76 mm across, 25 mm thick, 0.16 kg; sliding
friction 0.2 with the table) at rest on the table at (0.55, 0.134) m, in front of the robot. The bat's head
is a round blade 10 cm wide, 19 cm beyond the gripper's pinch point.

- **Randomised**: tau = ``target`` (``target_x``, ``target_y``: m on the table, in the world frame), drawn
  uniformly from the robot's box, x in [1.4, 1.7] m and y in [-0.05, 0.32] m on the UR5e
  (:data:`~besman.tasks.puck_strike.rollouts.BOUNDS`) - beyond the arm's reach: with the arm stretched and
  the bat tilted its head reaches x <= 1.26 m on the table along the puck's line; without a seed the middle,
  (1.55, 0.135) m.
- **Success**: the puck is at rest - its speed below 0.01 m/s
  (:data:`~besman.tasks.puck_strike.rollouts.REST_SPEED`) - on the table, with its centre within 0.05 m
  (:data:`~besman.tasks.puck_strike.rollouts.SUCCESS_RADIUS`) of the target in the table's plane
  (:func:`~besman.tasks.puck_strike.rollouts.judge`).

Policy search (``batched``) evaluates theta, the 72 parameters of the arm's joint-space DMP, for many targets
at once on :class:`~besman.tasks.puck_strike.rollouts.PuckStrikeRollouts` (reward: minus the distance from
where the puck comes to rest to the target, +1 for a success). The default tree (``puck_strike.yaml``,
``besman demo puck-strike``) instantiates the skill template over the target (``examples/pools/puck_strike``)
for the run's target, refines it in simulation where it would miss (:mod:`~besman.tasks.puck_strike.leaves`)
and strikes it in the run's world (:mod:`besman.sim.open_loop_executor`: the rollouts' control rows, step by
step, judged by the rollouts' rule, so the run's outcome is the rollouts'); a run can also be driven by joint
targets (``TaskEnv``'s ``joint`` control).
"""

from __future__ import annotations

from collections.abc import Mapping
from typing import ClassVar

import numpy as np

from besman.sim.open_loop_task import OpenLoopTask
from besman.tasks.base import Scene, Task, TaskValue


class PuckStrike(OpenLoopTask, Task):
    name = "puck-strike"
    controls = ("joint",)
    title = "the UR5e strikes a puck with a bat so that it slides to a target beyond its reach"
    randomised = "the target on the table (tau)"
    success = "the puck at rest on the table with its centre within 0.05 m of the target"
    robot = "ur5e"
    tree = "puck_strike.yaml"
    values = (
        TaskValue(
            "target",
            ("target_x", "target_y"),
            "m",
            "where the puck should come to rest on the table",
            surface="table",
            target=True,
        ),
    )
    measurements: ClassVar[Mapping[str, str]] = {
        "target": "where the puck should come to rest, x, y on the table (m)",
        "puck": "where the puck is, x, y (m)",
        "miss_m": "the puck's distance from the target in the table's plane (success: within 0.05 m)",
        "puck_speed_m_s": "the puck's speed (at rest: below 0.01 m/s)",
    }
    max_sim_time = 10.0
    rollouts = "besman.tasks.puck_strike.rollouts.PuckStrikeRollouts"

    def scene(self, robot: str, values, seed: int | None) -> Scene:
        import mujoco

        from besman.sim.open_loop_executor import OpenLoopExecutor
        from besman.tasks.puck_strike.world import puck_strike_world

        target = np.asarray(values["target"], dtype=float)
        world = puck_strike_world()
        rollouts = self.batched(robot)  # the template's leaves simulate strikes in it, apart from this world
        start = rollouts.start_state()
        mujoco.mj_setState(world.model, world.data, start, mujoco.mjtState.mjSTATE_FULLPHYSICS.value)
        mujoco.mj_forward(world.model, world.data)
        # The strike ends with the rollout's last step, the run with it: the task's rule on the world as it
        # stands is then the rollouts' rule on that step's sensors (the same function, the same values).
        executor = OpenLoopExecutor(world, rollouts, target)
        return Scene(executor, dict(values), {"target": target.tolist()}, lambda: self.judge(world, target))

    def judge(self, world, target):
        """The success rule on the world as it stands (see the module documentation)."""
        from besman.tasks.puck_strike.rollouts import judge
        from besman.trees.summary import Measured

        model, data = world.model, world.data
        position = data.sensordata[model.sensor("puck_position").adr[0] :][:3].copy()
        velocity = data.sensordata[model.sensor("puck_velocity").adr[0] :][:3].copy()
        success, _, _, sliding = judge(position, velocity, target)
        miss = float(np.linalg.norm(position[:2] - target))
        speed = float(np.linalg.norm(velocity))
        puck = np.round(position[:2], 3)
        return Measured(
            success,
            f"the puck is {'sliding' if sliding else 'at rest'} at {puck.tolist()}, {miss:.3f} m from the "
            f"target {np.round(target, 3).tolist()}",
            {
                "target": np.round(target, 4).tolist(),
                "puck": puck.tolist(),
                "miss_m": round(miss, 4),
                "puck_speed_m_s": round(speed, 4),
            },
        )


TASKS = (PuckStrike(),)
