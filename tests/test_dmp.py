"""Joint-space DMPs with goal velocity: the published equations, imitation, generation, theta."""

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from scipy.integrate import solve_ivp

from besman.skills import DMP, DMPSettings
from besman.skills.transformation import minimum_jerk, moving_goal_basis

finite = st.floats(-2.0, 2.0, allow_nan=False)


def wavy_demo(n=501, duration=1.2, dims=3, phase=0.0):
    times = np.linspace(0.0, duration, n)
    s = times / duration
    positions = np.column_stack(
        [
            (0.3 + 0.2 * d) * minimum_jerk(s)
            + 0.1 * np.sin(np.pi * s + phase) ** 2 * (-1) ** d
            + 0.05 * (1 - np.cos(2 * np.pi * s))
            for d in range(dims)
        ]
    )
    return times, positions


@settings(max_examples=40, deadline=None)
@given(
    start=st.lists(finite, min_size=2, max_size=2),
    goal=st.lists(finite, min_size=2, max_size=2),
    start_velocity=st.lists(finite, min_size=2, max_size=2),
    goal_velocity=st.lists(finite, min_size=2, max_size=2),
    execution_time=st.floats(0.3, 3.0),
)
def test_start_goal_and_goal_velocity_are_met_exactly(
    start, goal, start_velocity, goal_velocity, execution_time
):
    dmp = DMP(
        2,
        execution_time=execution_time,
        dt=0.01,
        start=start,
        goal=goal,
        start_velocity=start_velocity,
        goal_velocity=goal_velocity,
    )
    trajectory = dmp.trajectory()
    np.testing.assert_allclose(trajectory.positions[0], start, atol=1e-9)
    np.testing.assert_allclose(trajectory.velocities[0], start_velocity, atol=1e-9)
    np.testing.assert_allclose(trajectory.positions[-1], goal, atol=1e-9)
    np.testing.assert_allclose(trajectory.velocities[-1], goal_velocity, atol=1e-9)
    assert trajectory.times[-1] == pytest.approx(execution_time)


def test_generation_solves_the_published_transformation_system():
    """Against an accurate ODE solution of Muelling et al.'s equation with random weights."""
    rng = np.random.default_rng(1)
    dmp = DMP(
        2,
        execution_time=0.8,
        dt=0.004,
        start=[0.1, -0.2],
        start_velocity=[0.3, 0.0],
        start_acceleration=[1.0, -0.5],
        goal=[0.7, 0.4],
        goal_velocity=[0.5, -0.2],
    )
    dmp.weights = rng.normal(0, 200, size=dmp.weights.shape)
    trajectory = dmp.trajectory(run_time=1.2)
    tau, alpha, beta = 0.8, 25.0, 6.25
    boundary = np.stack(
        [
            dmp.start,
            tau * dmp.start_velocity,
            tau**2 * dmp.start_acceleration,
            dmp.goal,
            tau * dmp.goal_velocity,
            np.zeros(2),
        ]
    )

    def moving_goal(t):
        position, velocity, acceleration = (b[0] @ boundary for b in moving_goal_basis(np.array([t / tau])))
        return position, velocity / tau, acceleration / tau**2

    def rhs(t, x):
        y, yd = x[:2], x[2:]
        g, gd, gdd = moving_goal(t)
        f = dmp.basis.features(np.array([t / tau]))[0] @ dmp.weights.T
        return np.concatenate([yd, (alpha * (beta * (g - y) + tau * (gd - yd)) + f) / tau**2 + gdd])

    solution = solve_ivp(
        rhs,
        (0, 1.2),
        np.concatenate([dmp.start, dmp.start_velocity]),
        t_eval=trajectory.times,
        rtol=1e-11,
        atol=1e-12,
        max_step=1e-3,
    )
    amplitude = np.ptp(solution.y[:2], axis=1)
    assert np.max(np.abs(solution.y[:2].T - trajectory.positions) / amplitude) < 1e-6
    assert np.max(np.abs(solution.y[2:].T - trajectory.velocities) / np.ptp(solution.y[2:], axis=1)) < 1e-5
    accelerations = np.array([rhs(t, x)[2:] for t, x in zip(solution.t, solution.y.T, strict=True)])
    assert np.max(np.abs(accelerations - trajectory.accelerations) / np.ptp(accelerations, axis=0)) < 1e-4


def test_imitating_a_minimum_jerk_movement_reproduces_it():
    times = np.linspace(0, 2.0, 201)
    positions = np.column_stack([0.2 + 1.1 * minimum_jerk(times / 2.0), -0.4 * minimum_jerk(times / 2.0)])
    dmp = DMP(2, dt=0.01).imitate(times, positions)
    trajectory = dmp.trajectory()
    rmse = np.sqrt(np.mean((trajectory.positions - positions) ** 2, axis=0))
    assert np.all(rmse < 0.01 * np.ptp(positions, axis=0))
    assert dmp.execution_time == pytest.approx(2.0)


def test_imitating_a_curved_movement_with_ten_weights():
    times, positions = wavy_demo()
    dmp = DMP(3, dt=times[1]).imitate(times, positions)
    trajectory = dmp.trajectory()
    rmse = np.sqrt(np.mean((trajectory.positions - positions) ** 2, axis=0))
    assert np.all(rmse < 0.01 * np.ptp(positions, axis=0))
    np.testing.assert_allclose(trajectory.positions[-1], positions[-1], atol=0.01 * np.ptp(positions))


def test_imitating_several_demonstrations_gives_their_mean_shape():
    def shape(s):
        return np.column_stack([0.5 * minimum_jerk(s) + 0.05 * np.sin(2 * np.pi * s), -0.3 * minimum_jerk(s)])

    def variation(s):
        return 0.1 * np.sin(np.pi * s)[:, None] * [1.0, -1.0]

    # Two variations around one shape, recorded at different speeds: time normalisation aligns them.
    fast, slow = np.linspace(0, 1.0, 301), np.linspace(0, 1.5, 451)
    several = DMP(2, dt=0.01).imitate(
        [fast, slow], [shape(fast) + variation(fast), shape(slow / 1.5) - variation(slow / 1.5)]
    )
    assert several.execution_time == pytest.approx(1.25)
    mean_times = np.linspace(0, 1.25, 376)
    single = DMP(2, dt=0.01).imitate(mean_times, shape(mean_times / 1.25))
    np.testing.assert_allclose(several.trajectory().positions, single.trajectory().positions, atol=1e-4)
    np.testing.assert_allclose(several.goal, shape(np.array([1.0]))[0], atol=1e-12)


def test_time_scaling_keeps_the_path():
    times, positions = wavy_demo()
    dmp = DMP(3, dt=0.01).imitate(times, positions)
    original = dmp.trajectory()
    # Three times slower: boundary velocities scale by 1/3 and accelerations by 1/9, and the path stays.
    dmp.configure(
        execution_time=3 * dmp.execution_time,
        dt=0.03,
        start_velocity=dmp.start_velocity / 3,
        start_acceleration=dmp.start_acceleration / 9,
        goal_velocity=dmp.goal_velocity / 3,
    )
    slower = dmp.trajectory()
    np.testing.assert_allclose(slower.positions, original.positions, atol=1e-9)
    np.testing.assert_allclose(slower.velocities * 3, original.velocities, atol=1e-9)
    np.testing.assert_allclose(slower.accelerations * 9, original.accelerations, atol=1e-7)


def test_new_goal_and_start_reshape_the_movement_smoothly():
    times, positions = wavy_demo()
    dmp = DMP(3, dt=0.01).imitate(times, positions)
    shape = dmp.trajectory().positions - dmp.trajectory().positions[[0]]
    dmp.configure(goal=dmp.goal + 0.2, start=dmp.start - 0.1)
    moved = dmp.trajectory()
    np.testing.assert_allclose(moved.positions[0], dmp.start, atol=1e-12)
    np.testing.assert_allclose(moved.positions[-1], dmp.goal, atol=0.01)
    # The deviation from the straight quintic is unchanged: the shape survives the new boundary values.
    assert np.max(np.abs(np.diff(moved.positions, 2, axis=0))) < 10 * np.max(
        np.abs(np.diff(shape, 2, axis=0))
    )


def test_running_past_the_execution_time_converges_to_the_goal():
    dmp = DMP(1, dt=0.01, goal=[1.0], goal_velocity=[0.5])
    trajectory = dmp.trajectory(run_time=3.0)
    index = np.searchsorted(trajectory.times, 1.0)
    assert trajectory.velocities[index, 0] == pytest.approx(0.5, abs=1e-6), "velocity continuous at tau"
    assert trajectory.positions[-1, 0] == pytest.approx(1.0, abs=1e-6)
    assert trajectory.velocities[-1, 0] == pytest.approx(0.0, abs=1e-6)


@settings(max_examples=25, deadline=None)
@given(seed=st.integers(0, 10_000), population=st.integers(1, 9))
def test_batched_and_single_generation_agree(seed, population):
    rng = np.random.default_rng(seed)
    dmp = DMP(4, dt=0.02, start=rng.normal(size=4), start_velocity=rng.normal(size=4))
    thetas = rng.normal(size=(population, dmp.n_params)) * 3
    batch = dmp.trajectories(thetas)
    for theta, positions, velocities, accelerations in zip(
        thetas, batch.positions, batch.velocities, batch.accelerations, strict=True
    ):
        single = dmp.trajectory(theta)
        # Bit for bit, not just to 1e-9: how a population is split must not change any result.
        np.testing.assert_array_equal(positions, single.positions)
        np.testing.assert_array_equal(velocities, single.velocities)
        np.testing.assert_array_equal(accelerations, single.accelerations)


def test_theta_layout_and_round_trip():
    dmp = DMP(7, scale=0.1)
    assert dmp.n_params == 84
    assert DMP(8).n_params == 96
    rng = np.random.default_rng(0)
    theta = rng.normal(size=84)
    dmp.set_params(theta)
    np.testing.assert_allclose(dmp.get_params(), theta, atol=1e-12)
    blocks = theta.reshape(7, 12)
    np.testing.assert_allclose(dmp.goal, 0.1 * blocks[:, 10])
    np.testing.assert_allclose(dmp.goal_velocity, 0.1 * blocks[:, 11] / dmp.execution_time)


def test_a_unit_step_of_any_weight_moves_the_path_by_at_most_the_scale():
    dmp = DMP(1, dt=0.001, scale=0.1)
    base = dmp.trajectory().positions[:, 0]
    for i in range(dmp.n_weights):
        theta = np.zeros(dmp.n_params)
        theta[i] = 1.0
        displacement = np.abs(dmp.trajectory(theta).positions[:, 0] - base).max()
        assert displacement == pytest.approx(0.1, rel=1e-3), f"weight {i}"


@pytest.mark.parametrize(
    ("call", "message"),
    [
        (lambda d: d.imitate(np.linspace(0, 1, 50), np.full((50, 2), np.nan)), "positions contains NaN"),
        (
            lambda d: d.imitate(np.linspace(0, 1, 50), np.full((50, 2), np.inf)),
            "positions contains NaN or inf",
        ),
        (lambda d: d.imitate(np.r_[0, 0.5, 0.5, 1.0], np.zeros((4, 2))), "strictly increasing"),
        (lambda d: d.imitate(np.linspace(0, 1, 50), np.zeros((49, 2))), r"shape \(50, 2\)"),
        (lambda d: d.imitate(np.linspace(0, 1, 50), np.zeros((50, 3))), r"shape \(50, 2\)"),
        (lambda d: d.imitate([np.linspace(0, 1, 5)], []), "as many time arrays"),
        (lambda d: d.trajectory(np.zeros(5)), "theta must have 24 entries"),
        (lambda d: d.trajectory(np.full(24, np.nan)), "theta contains NaN"),
        (lambda d: d.trajectories(np.zeros((3, 23))), r"thetas must have shape \(N, 24\)"),
        (lambda d: d.set_params(np.zeros(25)), "theta must have 24 entries"),
        (lambda d: d.configure(goal=[1, 2, 3]), r"goal must have shape \(2,\)"),
        (lambda d: d.configure(execution_time=0), "execution_time must be a finite positive"),
        (lambda d: d.configure(speed=2), "unknown meta-parameter 'speed'"),
        (lambda d: d.configure(scale=[0.1, -1]), "scale must be positive"),
        (lambda d: DMP(0), "n_dims must be a positive integer"),
        (lambda d: DMP(2, settings=DMPSettings(n_weights=1)), "n_weights must be an integer >= 2"),
        (lambda d: DMP(2, dt=float("nan")), "dt must be a finite positive number"),
    ],
)
def test_bad_input_is_a_clear_value_error(call, message):
    with pytest.raises(ValueError, match=message):
        call(DMP(2))
