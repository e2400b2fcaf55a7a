"""Ball-in-a-cup: the UR5e swings a ball on a string up and catches it in the cup it holds (after Kober &
Peters, "Policy search for motor primitives in robotics", NIPS 2009), a skill no planner scripts:
:mod:`besman.tasks.ball_in_cup.rollouts` (the batched rollouts of policy search),
:mod:`~besman.tasks.ball_in_cup.world` (the cup, the ball and the string in MuJoCo),
:mod:`~besman.tasks.ball_in_cup.demonstration` (a synthetic demonstration that misses, and its imitation)
and :mod:`~besman.tasks.ball_in_cup.baseline` (the best hand-written motion).

The run starts with the arm at rest in :data:`~besman.tasks.ball_in_cup.rollouts.START`, the cup upright in
front of the robot (9 cm inner diameter, 8 cm deep, held by a handle in the gripper), the ball (4 cm, 25 g)
hanging still under it on a string tied under the cup's bottom.

- **Randomised**: tau = ``string`` (``string_length``: m from the knot under the cup to the ball's centre),
  drawn uniformly from the robot's box, [0.30, 0.45] m on the UR5e
  (:data:`~besman.tasks.ball_in_cup.rollouts.BOUNDS`); without a seed the middle, 0.375 m.
- **Success**: the ball's centre is inside the cup - in the cup's frame (origin at the centre of the inner
  bottom, z along the cup's axis towards the opening) 0 <= z < 0.08 m (below the rim) and sqrt(x^2 + y^2)
  < 0.045 m (within the inner radius) - at every step of the run's last 0.25 s
  (:data:`~besman.tasks.ball_in_cup.rollouts.SETTLE_TIME`): it went in after the swing and is still inside
  at the end (:func:`~besman.tasks.ball_in_cup.rollouts.judge`).

Policy search (``batched``) evaluates theta, the 72 parameters of the arm's joint-space DMP, for many string
lengths at once on :class:`~besman.tasks.ball_in_cup.rollouts.BallInCupRollouts`. The default tree
(``ball_in_cup.yaml``, ``besman demo ball-in-cup``) instantiates the skill template over the string length
(``examples/pools/ball_in_cup``, made by ``python -m besman.experiments.ball_in_cup``) for the run's string,
refines it in simulation where it would miss (:mod:`~besman.tasks.ball_in_cup.leaves`) and swings it in the
run's world (:mod:`besman.sim.open_loop_executor`); a run can also be driven by joint targets (``TaskEnv``'s
``joint`` control).
"""

from __future__ import annotations

from collections.abc import Mapping
from typing import ClassVar

import numpy as np

from besman.sim.open_loop_task import OpenLoopTask
from besman.tasks.base import Scene, Task, TaskValue


class BallInCup(OpenLoopTask, Task):
    name = "ball-in-cup"
    controls = ("joint",)
    title = "the UR5e swings a ball on a string up and catches it in the cup it holds"
    randomised = "the string's length (tau)"
    success = "the ball inside the cup (below the rim, within its radius) for the run's last 0.25 s"
    robot = "ur5e"
    tree = "ball_in_cup.yaml"
    values = (
        TaskValue(
            "string", ("string_length",), "m", "the string's length, from its knot to the ball's centre"
        ),
    )
    measurements: ClassVar[Mapping[str, str]] = {
        "string_length": "the string's length (m)",
        "ball_in_cup": "the ball's centre at the end, x, y, z in the cup's frame (m)",
        "inside_s": "how long the ball has been inside the cup without a break at the end (s)",
    }
    max_sim_time = 10.0
    rollouts = "besman.tasks.ball_in_cup.rollouts.BallInCupRollouts"

    def scene(self, robot: str, values, seed: int | None) -> Scene:
        import mujoco

        from besman.sim.open_loop_executor import OpenLoopExecutor
        from besman.tasks.ball_in_cup.world import ball_in_cup_world

        length = float(values["string"][0])
        world = ball_in_cup_world(length)
        rollouts = self.batched(robot)  # the template's leaves simulate swings in it, apart from this world
        start = rollouts.start_state(length)
        mujoco.mj_setState(world.model, world.data, start, mujoco.mjtState.mjSTATE_FULLPHYSICS.value)
        mujoco.mj_forward(world.model, world.data)
        executor = OpenLoopExecutor(world, rollouts, [length])
        history: list[tuple[float, np.ndarray]] = []
        sensor = world.model.sensor("ball_in_cup").adr[0]

        def observe(runner, record) -> None:
            data = world.data
            history.append((float(data.time), data.sensordata[sensor : sensor + 3].copy()))

        def judge():
            return self.judge(world, history, length)

        return Scene(executor, dict(values), {"string": [length]}, judge, observe)

    def judge(self, world, history, length):
        """The success rule on a run: the ball's positions in the cup's frame that the scene's observer
        recorded, and where the ball is now."""
        from besman.tasks.ball_in_cup.rollouts import SETTLE_TIME, inside_cup
        from besman.trees.summary import Measured

        sensor = world.model.sensor("ball_in_cup").adr[0]
        now = (float(world.data.time), world.data.sensordata[sensor : sensor + 3].copy())
        samples = [*history, now] if not history or history[-1][0] < now[0] else history
        times = np.array([t for t, _ in samples])
        inside = inside_cup(np.array([p for _, p in samples]))
        outside = np.flatnonzero(~inside)
        since = times[outside[-1]] if outside.size else times[0] - world.model.opt.timestep
        inside_for = float(times[-1] - since) if inside[-1] else 0.0
        success = bool(inside[-1]) and inside_for >= SETTLE_TIME
        position = np.round(now[1], 4)
        return Measured(
            success,
            f"the ball is {'inside' if inside[-1] else 'outside'} the cup at {position.tolist()} "
            "(cup frame), "
            f"inside for {inside_for:.2f} s",
            {"string_length": length, "ball_in_cup": position.tolist(), "inside_s": round(inside_for, 3)},
        )


TASKS = (BallInCup(),)
