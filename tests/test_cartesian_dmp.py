"""Cartesian DMPs: position plus unit-quaternion orientation (Ude et al. 2014)."""

import numpy as np
import pytest
from helpers import rotation_angle
from hypothesis import given, settings
from hypothesis import strategies as st

from besman.skills import CartesianDMP
from besman.skills import quaternion as quat
from besman.skills.transformation import minimum_jerk


def demo(n=501, duration=1.0, angle=1.0):
    times = np.linspace(0.0, duration, n)
    s = times / duration
    positions = np.column_stack(
        [0.3 * minimum_jerk(s), 0.1 * np.sin(np.pi * s) ** 2, 0.2 - 0.1 * minimum_jerk(s)]
    )
    rotations = np.column_stack(
        [angle * minimum_jerk(s), 0.3 * np.sin(np.pi * s) ** 2, -0.5 * minimum_jerk(s)]
    )
    return times, positions, quat.from_rotation_vector(rotations)


def test_imitation_reproduces_position_and_orientation():
    times, positions, orientations = demo()
    dmp = CartesianDMP(dt=times[1]).imitate(times, positions, orientations)
    trajectory = dmp.trajectory()
    assert np.max(np.abs(trajectory.positions - positions)) < 0.01 * 0.3
    assert np.max(rotation_angle(trajectory.orientations, orientations)) < 0.01 * 1.0
    assert rotation_angle(trajectory.orientations[-1], orientations[-1]) < 0.01


@settings(max_examples=20, deadline=None)
@given(seed=st.integers(0, 10_000), spin=st.floats(0.0, 50.0))
def test_quaternions_stay_unit_norm(seed, spin):
    rng = np.random.default_rng(seed)
    dmp = CartesianDMP(
        dt=0.01,
        start_orientation=rng.normal(size=4),
        goal_orientation=rng.normal(size=4),
        start_angular_velocity=rng.normal(size=3) * spin,
    )
    theta = dmp.get_params() + rng.normal(size=dmp.n_params) * 5
    trajectory = dmp.trajectory(theta, run_time=2.0)
    np.testing.assert_allclose(np.linalg.norm(trajectory.orientations, axis=-1), 1.0, atol=1e-12)


def test_orientation_converges_to_the_goal():
    goal = quat.from_rotation_vector(np.array([0.3, -1.2, 2.0]))
    dmp = CartesianDMP(dt=0.01, goal_orientation=goal)
    trajectory = dmp.trajectory(run_time=3.0)
    assert rotation_angle(trajectory.orientations[-1], goal) < 1e-4
    assert np.linalg.norm(trajectory.angular_velocities[-1]) < 1e-3


def test_the_integrator_is_second_order_accurate(monkeypatch):
    import besman.skills.cartesian_dmp as module

    times, positions, orientations = demo(n=201, angle=2.5)
    dmp = CartesianDMP(dt=0.01).imitate(times, positions, orientations)
    errors = []
    monkeypatch.setattr(module, "STEP_FRACTION", 1e-5)
    reference = dmp.trajectory().orientations
    for fraction in (1e-2, 1e-3):
        monkeypatch.setattr(module, "STEP_FRACTION", fraction)
        errors.append(np.max(rotation_angle(dmp.trajectory().orientations, reference)))
    assert errors[1] < 1e-5
    assert errors[0] / errors[1] == pytest.approx(100, rel=0.2), "error falls with the square of the step"


def test_batched_and_single_generation_agree():
    rng = np.random.default_rng(4)
    times, positions, orientations = demo(n=101)
    dmp = CartesianDMP(dt=0.01).imitate(times, positions, orientations)
    thetas = dmp.get_params() + rng.normal(size=(5, dmp.n_params))
    batch = dmp.trajectories(thetas)
    for i, theta in enumerate(thetas):
        single = dmp.trajectory(theta)
        for name in (
            "positions",
            "velocities",
            "orientations",
            "angular_velocities",
            "angular_accelerations",
        ):
            np.testing.assert_allclose(getattr(batch, name)[i], getattr(single, name), rtol=0, atol=1e-9)


def test_theta_round_trip_and_layout():
    dmp = CartesianDMP(rotation_scale=0.2)
    assert dmp.n_params == 3 * 12 + 3 * 11
    rng = np.random.default_rng(0)
    theta = rng.normal(size=dmp.n_params)
    dmp.set_params(theta)
    np.testing.assert_allclose(dmp.get_params(), theta, atol=1e-12)
    goal_rotation = theta[36:].reshape(3, 11)[:, -1] * 0.2
    np.testing.assert_allclose(quat.rotation_vector(dmp.goal_orientation), goal_rotation, atol=1e-12)


def test_several_demonstrations_average_the_goal_orientation():
    times, positions, orientations = demo(n=201, angle=1.0)
    _, _, turned = demo(n=201, angle=1.4)
    dmp = CartesianDMP(dt=0.01).imitate([times, times], [positions, positions], [orientations, turned])
    middle = quat.from_rotation_vector(np.array([1.2, 0.0, -0.5]))
    assert rotation_angle(dmp.goal_orientation, middle) < 0.01


@pytest.mark.parametrize(
    ("call", "message"),
    [
        (lambda: CartesianDMP(goal_orientation=[0, 0, 0, 0]), "goal_orientation has a zero-norm quaternion"),
        (lambda: CartesianDMP(start_orientation=[1, 0, 0]), "quaternions .* with 4 entries"),
        (lambda: CartesianDMP(start_orientation=[np.nan, 0, 0, 1]), "contains NaN"),
        (lambda: CartesianDMP().trajectory(np.zeros(3)), "theta must have 69 entries"),
        (lambda: CartesianDMP().imitate(*demo()[:2], np.zeros((501, 4))), "zero-norm quaternion"),
        (lambda: CartesianDMP().imitate(*demo()[:2], np.ones((500, 4))), r"shape \(501, 4\)"),
    ],
)
def test_bad_input_is_a_clear_value_error(call, message):
    with pytest.raises(ValueError, match=message):
        call()
