"""Outcome-space refinement: Gauss-Newton steps toward the target in a few coordinates of theta, the Jacobian
corrected by each trial's outcome (Broyden), the best outcome kept."""

import numpy as np
import pytest

from besman.core.errors import InputError
from besman.learning.search.outcome_refinement import refine_in_outcome_space

COORDINATES = np.array([1, 3, 4])
MIXING = np.array([[1.0, 0.5, 0.0], [0.2, -1.0, 0.7]])


def outcome(thetas):
    """A smooth nonlinear outcome of 3 of theta's 6 coordinates; the others are null space."""
    chosen = thetas[:, COORDINATES]
    return chosen @ MIXING.T + 0.2 * np.sin(2.0 * chosen[:, :2])


def problem(count=20, seed=0):
    rng = np.random.default_rng(seed)
    starts = rng.normal(size=(count, 6))
    targets = outcome(starts) + rng.uniform(-1.0, 1.0, size=(count, 2))
    wrong = np.tile(1.6 * MIXING, (count, 1, 1))  # the Jacobian of another place, and wrong
    return starts, targets, wrong


def no_guard(thetas, anchors):
    return thetas


def test_a_few_trials_reach_the_target_although_the_first_jacobian_is_wrong():
    starts, targets, wrong = problem()
    distances = refine_in_outcome_space(
        lambda thetas, _: outcome(thetas), no_guard, starts, outcome(starts), wrong, targets, COORDINATES, 5
    )
    assert distances.shape == (20, 6)
    assert np.all(np.diff(distances, axis=1) <= 1e-12)  # the best so far never worsens
    assert np.median(distances[:, 5]) < 0.02 * np.median(distances[:, 0])
    # Broyden's corrections matter: the wrong Jacobian kept for every step does worse.
    frozen = starts.copy()
    for _ in range(5):
        residual = targets - outcome(frozen)
        frozen[:, COORDINATES] += np.linalg.lstsq(1.6 * MIXING, residual.T, rcond=None)[0].T
    assert np.median(distances[:, 5]) < 0.5 * np.median(np.linalg.norm(targets - outcome(frozen), axis=1))


def test_steps_are_capped_and_guarded_and_failed_trials_cost_nothing_but_the_trial():
    starts, targets, wrong = problem(seed=1)
    targets = targets + 10.0  # far away: each step's predicted move is capped
    tried = []

    def failing_every_other_call(thetas, _):
        tried.append(thetas.copy())
        result = outcome(thetas)
        if len(tried) % 2 == 0:
            result[:] = np.nan
        return result

    def guard(thetas, anchors):  # nothing may move the null space
        assert np.array_equal(np.delete(thetas, COORDINATES, 1), np.delete(anchors, COORDINATES, 1))
        return thetas

    distances = refine_in_outcome_space(
        failing_every_other_call, guard, starts, outcome(starts), wrong, targets, COORDINATES, 4, step_cap=0.5
    )
    predicted_moves = np.linalg.norm((tried[0] - starts)[:, COORDINATES] @ (1.6 * MIXING).T, axis=1)
    assert predicted_moves == pytest.approx(np.full(20, 0.5))
    np.testing.assert_array_equal(distances[:, 2], distances[:, 1])  # the failed trial changed nothing
    assert np.all(distances[:, 3] < distances[:, 2])


def test_bad_input_is_refused_by_name():
    starts, targets, wrong = problem()
    with pytest.raises(InputError, match="Jacobians must be"):
        refine_in_outcome_space(no_guard, no_guard, starts, targets, wrong[:, :, :2], targets, COORDINATES, 2)
    with pytest.raises(InputError, match="one row per target"):
        refine_in_outcome_space(no_guard, no_guard, starts[:3], targets, wrong, targets, COORDINATES, 2)
    with pytest.raises(InputError, match="at least one trial"):
        refine_in_outcome_space(no_guard, no_guard, starts, targets, wrong, targets, COORDINATES, 0)


def test_the_result_does_not_depend_on_the_inputs_memory_layout():
    """A resumed experiment reads its Jacobians back contiguous where the first run computed them strided:
    the refinement must give the same bits either way."""
    starts, targets, wrong = problem(seed=2)
    strided = np.ascontiguousarray(wrong.transpose(0, 2, 1)).transpose(0, 2, 1)
    assert not strided.flags.c_contiguous

    def run(jacobians):
        return refine_in_outcome_space(
            lambda thetas, _: outcome(thetas),
            no_guard,
            starts,
            outcome(starts),
            jacobians,
            targets,
            COORDINATES,
            3,
        )

    np.testing.assert_array_equal(run(strided), run(np.ascontiguousarray(wrong)))
