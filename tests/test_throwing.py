"""The PA-10 throwing task: theta -> DMPs -> rollouts -> landing point -> reward."""

import numpy as np
import pytest

from besman.tasks.throwing.rollouts import (
    BROKEN_REWARD,
    FAILURE_REWARD,
    HARDWARE_BOUNDS,
    PAPER_BOUNDS,
    ThrowingConfig,
    ThrowingRollouts,
)


@pytest.fixture(scope="module")
def task():
    return ThrowingRollouts()


def test_theta_is_96_dimensional_and_bounds_are_the_papers(task):
    assert task.n_params == 96
    assert task.bounds == PAPER_BOUNDS
    assert task.bounds.as_dict() == {"x": [-7.0, -1.0], "y": [-5.0, 1.0]}


def test_the_hand_designed_throw_lands_near_the_papers_first_target(task):
    result = task.evaluate(task.default_theta(), [-3.5, -3.6])
    detail = result.details[0]
    assert detail.failure is None
    assert np.isfinite(result.rewards[0])
    landing = np.array(detail.landing)
    assert np.linalg.norm(landing - [-3.5, -3.6]) < 0.3
    assert result.rewards[0] == pytest.approx(-np.sum((landing - [-3.5, -3.6]) ** 2))
    assert 0.3 < detail.release_time < task.execution_time + 0.1


def test_rewards_are_reproducible_bit_for_bit(task):
    rng = np.random.default_rng(3)
    thetas = task.default_theta() + 0.3 * rng.normal(size=(6, task.n_params))
    taus = np.column_stack([rng.uniform(-7, -1, 6), rng.uniform(-5, 1, 6)])
    first = task.evaluate(thetas, taus)
    second = task.evaluate(thetas[::-1].copy(), taus[::-1].copy())  # other order, other threads
    np.testing.assert_array_equal(first.rewards, second.rewards[::-1])
    assert first.details == second.details[::-1]
    fresh = ThrowingRollouts().evaluate(thetas, taus)
    np.testing.assert_array_equal(first.rewards, fresh.rewards)


def test_landing_is_the_first_floor_contact(task):
    """The ball's centre reaches its radius above the floor at the landing point, before any bounce."""
    theta = task.default_theta()
    landings, _, failures, _ = task.throw(theta[None])
    assert failures == [None]
    controls, _, release_step, _ = task.controls(theta[None])
    _, ball, _ = task._rollout(controls)
    ground = np.flatnonzero(ball[0, :, 2] <= task.ball_radius + 1e-9)[0]
    assert ground > release_step[0]
    segment = ball[0, ground - 1 : ground + 1, :2]
    assert (
        np.min(np.linalg.norm(segment - landings[0], axis=1))
        < np.linalg.norm(segment[1] - segment[0]) + 1e-12
    )


def _perturbed_throws(task, count: int, seed: int) -> np.ndarray:
    rng = np.random.default_rng(seed)
    return task.default_theta() + 0.3 * rng.normal(size=(count, task.n_params))


def test_the_held_ball_touches_nothing(task):
    """Held 2 mm above the palm, the ball has no contact with the robot until it is released, also in
    perturbed throws (the weld sags a little under the swing)."""
    controls, failures, release_step, _ = task.controls(_perturbed_throws(task, 60, seed=11))
    valid = [i for i, failure in enumerate(failures) if failure is None]
    _, _, touches = task._rollout(controls[valid])
    held = np.arange(task.n_steps)[None, :] < release_step[valid][:, None]
    assert len(valid) > 30
    assert not (touches * held).any()


def test_a_ball_that_touches_the_robot_after_release_is_a_failed_throw(task):
    """Contact is real once the ball has left the hand: a throw whose arm sweeps back into the released ball
    scores the failure penalty and says so. Checked independently by stepping the throw with mj_step and
    looking for a ball-robot contact among MuJoCo's contacts after the release."""
    import mujoco

    thetas = _perturbed_throws(task, 40, seed=5)
    result = task.evaluate(thetas, np.tile([-3.5, -3.6], (40, 1)))
    hit = [
        i for i, detail in enumerate(result.details) if (detail.failure or "").startswith("the ball touches")
    ]
    clean = [i for i, detail in enumerate(result.details) if detail.failure is None]
    assert hit and clean
    assert result.rewards[hit[0]] == FAILURE_REWARD
    assert result.details[hit[0]].landing is None
    model, data = task.model, mujoco.MjData(task.model)
    robot = set(range(1, model.body("ball").id))  # the robot's bodies come before the ball
    ball = model.body("ball").id

    def touches_after_release(theta) -> bool:
        controls, _, release_step, _ = task.controls(theta[None])
        mujoco.mj_setState(model, data, task._initial_state, mujoco.mjtState.mjSTATE_FULLPHYSICS)
        for k in range(task.n_steps):
            data.ctrl[:] = controls[0, k, : model.nu]
            data.eq_active[task.weld] = controls[0, k, -1]
            mujoco.mj_step(model, data)
            if data.qpos[model.jnt_qposadr[model.body_jntadr[ball]] + 2] <= task.ball_radius:
                return False  # landed first
            bodies = model.geom_bodyid[data.contact.geom[: data.ncon]]
            if k >= release_step[0] and any(ball in pair and set(pair) & robot for pair in bodies.tolist()):
                return True
        return False

    assert touches_after_release(thetas[hit[0]])
    assert not touches_after_release(thetas[clean[0]])


def test_a_throw_that_never_releases_gets_the_failure_penalty(task):
    theta = task.default_theta().reshape(8, 12)
    theta[7, 10] = 0.0  # the release dimension's goal stays below the threshold
    result = task.evaluate(theta.ravel(), [-3.0, -3.0])
    assert "never released" in result.details[0].failure
    assert result.rewards[0] <= FAILURE_REWARD
    assert result.details[0].landing is None


def test_a_reference_beyond_the_speed_limits_is_a_failure_that_grows_with_the_violation(task):
    fast = task.default_theta().reshape(8, 12).copy()
    fast[1, 11] *= 2.0  # shoulder goal velocity doubled
    faster = fast.copy()
    faster[1, 11] *= 1.5
    result = task.evaluate(np.stack([fast.ravel(), faster.ravel()]), [-3.0, -3.0])
    assert all("exceeds the speed limit of joint S2" in d.failure for d in result.details)
    assert result.rewards[1] < result.rewards[0] < FAILURE_REWARD


def test_the_hardware_variant_throws_within_the_real_limits():
    hardware = ThrowingRollouts(ThrowingConfig(variant="hardware"))
    assert hardware.bounds == HARDWARE_BOUNDS
    np.testing.assert_array_equal(hardware.speed_limits, hardware.robot.group("arm").velocity)
    result = hardware.evaluate(hardware.default_theta(), [-1.2, 0.0])
    assert result.details[0].failure is None
    assert np.linalg.norm(np.array(result.details[0].landing) - [-1.15, 0.0]) < 0.2


@pytest.mark.parametrize(
    ("theta", "tau", "message"),
    [
        (np.zeros(95), [-3.0, -3.0], "theta must have 96 entries"),
        (np.full(96, np.nan), [-3.0, -3.0], "theta contains NaN"),
        (None, [-8.0, -3.0], r"tau x = -8 is outside the task's bounds \[-7, -1\]"),
        (None, [-3.0, 2.0], r"tau y = 2 is outside the task's bounds \[-5, 1\]"),
        (None, [-3.0], "tau must have 2 entries"),
        (None, [[-3.0, -3.0], [-2.0, -2.0]], "got 2 taus for 1 candidates"),
    ],
)
def test_bad_input_is_a_clear_value_error(task, theta, tau, message):
    with pytest.raises(ValueError, match=message):
        task.evaluate(task.default_theta() if theta is None else theta, tau)
    with pytest.raises(ValueError, match="backend must be one of"):
        task.evaluate(task.default_theta(), [-3.0, -3.0], backend="mpi")


def test_a_broken_theta_can_get_the_worst_penalty_instead_of_an_error(task):
    thetas = np.tile(task.default_theta(), (3, 1))
    thetas[1, 5] = np.nan
    result = task.evaluate(thetas, [-3.5, -3.6], nan="penalize")
    assert result.rewards[1] == BROKEN_REWARD
    assert result.details[1].failure == "theta contains NaN or inf"
    assert result.rewards[0] == result.rewards[2] > FAILURE_REWARD
    with pytest.raises(ValueError, match="theta contains NaN"):
        task.evaluate(thetas, [-3.5, -3.6])


def test_unknown_variant():
    with pytest.raises(ValueError, match="variant must be one of"):
        ThrowingRollouts(ThrowingConfig(variant="moon"))


@pytest.mark.slow
def test_ray_backend_gives_identical_landings(task):
    ray = pytest.importorskip("ray", reason="the 'distributed' extra")
    ray.init(num_cpus=2, include_dashboard=False, log_to_driver=False, ignore_reinit_error=True)
    try:
        rng = np.random.default_rng(11)
        thetas = task.default_theta() + 0.2 * rng.normal(size=(8, task.n_params))
        local = task.evaluate(thetas, [-3.5, -3.6])
        distributed = task.evaluate(thetas, [-3.5, -3.6], backend="ray")
        np.testing.assert_array_equal(local.rewards, distributed.rewards)
        assert local.details == distributed.details
        assert sum(d.failure is None for d in local.details) >= 4
    finally:
        ray.shutdown()


def test_feasible_is_the_reference_check_evaluate_makes_before_it_simulates(task):
    """The guard's check costs no rollout and agrees with evaluate: a theta it calls infeasible fails there
    for its reference's sake, one it passes fails (if at all) only in the simulation."""
    rng = np.random.default_rng(11)
    thetas = task.default_theta() + rng.normal(size=(24, task.n_params)) * np.linspace(0.0, 4.0, 24)[:, None]
    thetas[3] = np.nan
    feasible = task.feasible(thetas)
    assert feasible[0] and not feasible[3] and feasible.sum() not in (0, len(thetas) - 1)
    details = task.evaluate(thetas, np.tile([-3.5, -3.6], (len(thetas), 1)), nan="penalize").details
    reference_failures = ("the reference", "never released", "theta contains NaN")
    for ok, detail in zip(feasible, details, strict=True):
        assert ok != (detail.failure is not None and detail.failure.startswith(reference_failures)), detail


def test_the_aim_refines_a_missing_throw_and_keeps_it_only_beyond_the_noise():
    """At a corner target the template's throw misses by 0.35 m (more than the aim's 0.25): the leaf
    refines it in simulation, throws the template's and the best once more (the throws reproduce: noise 0)
    and keeps the best, which gained; its message says so."""
    from besman.tasks.running import prepare

    prepared = prepare("throwing", values={"target": np.array([-1.1, 0.9])})
    prepared.runner.run()
    aim = next(node for node in prepared.runner.root.iterate() if node.name == "aim")
    assert aim.acceptance.noise == 0.0 and aim.acceptance.evaluations == 2
    assert aim.acceptance.accepted and aim.acceptance.improvement > 0
    assert aim.expected_miss < 0.25 and aim.rollouts == 20
    assert "misses by 0.35 m; after 20 simulated throws: 0.21 m" in aim.feedback_message
    assert "noise 0 over 2 evaluations: kept" in aim.feedback_message
