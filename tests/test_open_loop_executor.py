"""The open-loop executor: a theta of a task's open-loop rollouts run in the task's running world, one physics
step at a time, judged by the rollouts' own rule - the same outcome as the rollouts', bit for bit (here the
puck strike's; ball-in-a-cup's swing: tests/test_ball_in_cup.py) - and what it refuses."""

import mujoco
import numpy as np
import pytest
from helpers import closing

from besman import examples
from besman.core.errors import InputError
from besman.sim.motions import MotionStatus
from besman.sim.open_loop_executor import OpenLoopExecutor
from besman.tasks.ball_in_cup.rollouts import BallInCupRollouts
from besman.tasks.puck_strike.demonstration import FILE, imitate, load_demonstration
from besman.tasks.puck_strike.rollouts import PuckStrikeRollouts
from besman.tasks.puck_strike.world import puck_strike_world

TARGET = np.array([1.55, 0.135])


@pytest.fixture(scope="module")
def puck_strike():
    yield from closing(PuckStrikeRollouts())


@pytest.fixture(scope="module")
def ball_in_cup():
    yield from closing(BallInCupRollouts())


@pytest.fixture(scope="module")
def strike(puck_strike):
    """The imitated demonstration's strike: it moves the puck, and misses."""
    return imitate(puck_strike, *load_demonstration(examples.path("data") / FILE))


def _at_start(world, start_state) -> None:
    mujoco.mj_setState(world.model, world.data, start_state, mujoco.mjtState.mjSTATE_FULLPHYSICS.value)
    mujoco.mj_forward(world.model, world.data)


def puck_strike_executor(rollouts, tau=TARGET) -> OpenLoopExecutor:
    world = puck_strike_world()
    _at_start(world, rollouts.start_state())
    return OpenLoopExecutor(world, rollouts, tau)


def run_to_the_end(executor, theta):
    motion = executor.start_motion(theta)
    while executor.advance(10) is MotionStatus.RUNNING:
        pass
    return motion


def test_a_strike_in_the_running_world_is_the_rollouts_bit_for_bit(puck_strike, strike):
    executor = puck_strike_executor(puck_strike)
    motion = run_to_the_end(executor, strike)
    expected = puck_strike.evaluate(strike, TARGET)
    assert motion.reward == expected.rewards[0]  # bit for bit
    assert motion.detail == expected.details[0] and motion.detail.moved and not motion.detail.success
    assert motion.status is MotionStatus.FAILED and motion.step == puck_strike.n_steps
    # The states and sensors recorded are those of MuJoCo's rollout, every step.
    positions, velocities = puck_strike.references(strike[None])
    states, sensors = puck_strike._run(positions, velocities, TARGET[None])
    np.testing.assert_array_equal(motion.states, states[0])
    np.testing.assert_array_equal(motion.sensors, sensors[0])
    # The arm is handed back to the executor where the strike left it.
    assert executor.open_loop is motion and executor.motion is None
    np.testing.assert_array_equal(executor.position, executor.arm.measured())


def test_a_theta_of_the_wrong_size_or_not_finite_is_refused(puck_strike, strike):
    executor = puck_strike_executor(puck_strike)
    with pytest.raises(InputError, match=r"theta must have shape \(72,\), got \(5,\)"):
        executor.start_motion(np.zeros(5))
    bad = strike.copy()
    bad[3] = np.nan
    with pytest.raises(InputError, match=r"theta contains NaN or inf \(first at index \(3,\)"):
        executor.start_motion(bad)
    assert executor.open_loop is None


def test_a_motion_starts_only_with_the_arm_in_the_start_pose(puck_strike, strike):
    executor = puck_strike_executor(puck_strike)
    world = executor.world
    world.data.qpos[executor.arm.qpos_indices[0]] += 0.1  # the shoulder pan turned by 0.1 rad
    mujoco.mj_forward(world.model, world.data)
    with pytest.raises(
        InputError,
        match=r"starts with the arm at rest in the task's start pose \[-1\.5708, .*\]; the arm is at "
        r"\[-1\.4708, ",
    ):
        executor.start_motion(strike)


def test_a_reference_the_rollouts_refuse_is_refused_with_their_reason(puck_strike, strike):
    executor = puck_strike_executor(puck_strike)
    with pytest.raises(InputError, match="theta cannot be executed: the reference leaves the range of joint"):
        executor.start_motion(strike * 20)


def test_the_executor_needs_the_tasks_rollouts_world_and_a_tau_in_its_box(puck_strike, ball_in_cup):
    world = puck_strike_world()
    with pytest.raises(InputError, match="rollouts must be an OpenLoopRollouts"):
        OpenLoopExecutor(world, object(), TARGET)
    with pytest.raises(InputError, match=r"tau target_x = 1 is outside the task's bounds \[1\.4, 1\.7\]"):
        OpenLoopExecutor(world, puck_strike, [1.0, 0.1])
    with pytest.raises(InputError, match="not the task's world"):
        OpenLoopExecutor(world, ball_in_cup, [0.4])


def test_without_an_open_loop_motion_it_is_the_robots_executor(puck_strike):
    """Between motions the arm holds as any executor's does (joint control, a tree's other leaves)."""
    executor = puck_strike_executor(puck_strike)
    before = executor.arm.measured().copy()
    assert executor.advance(25) is MotionStatus.SUCCEEDED
    assert executor.time == pytest.approx(25 * executor.config.control_period)
    np.testing.assert_allclose(executor.arm.measured(), before, atol=1e-3)
