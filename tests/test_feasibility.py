"""The free feasibility guard: infeasible proposals are pulled back toward a feasible anchor by halving, and
counted; feasible ones are left alone."""

import numpy as np
import pytest

from besman.experiments.throwing.bench import ThrowingBench, validation_targets
from besman.experiments.throwing.config import ExperimentConfig
from besman.experiments.throwing.contextual import GuardedPolicy
from besman.learning.search.contextual import CREPS, ContextBox
from besman.learning.search.feasibility import MAX_HALVINGS, pull_back


def inside_unit_ball(thetas):
    return np.linalg.norm(thetas, axis=1) <= 1.0


def test_an_infeasible_proposal_is_halved_toward_its_anchor_until_feasible():
    proposals = np.array([[0.5, 0.0], [3.0, 0.0], [0.0, -10.0]])
    anchors = np.zeros((3, 2))
    pulled, moved = pull_back(proposals, anchors, inside_unit_ball)
    np.testing.assert_array_equal(moved, [False, True, True])
    np.testing.assert_allclose(pulled, [[0.5, 0.0], [0.75, 0.0], [0.0, -0.625]])  # 3/4, 10/16
    np.testing.assert_array_equal(proposals[1], [3.0, 0.0])  # the input is not changed


def test_a_proposal_that_never_becomes_feasible_is_replaced_by_its_anchor():
    def only_the_anchor(thetas):
        return np.all(thetas == 7.0, axis=1)

    pulled, moved = pull_back(np.array([[7.0 + 2.0**MAX_HALVINGS]]), np.array([[7.0]]), only_the_anchor)
    assert moved[0] and only_the_anchor(pulled)[0]


@pytest.fixture(scope="module")
def bench():
    return ThrowingBench(ExperimentConfig.quick(), progress=False)


def test_the_throwing_guard_makes_wild_proposals_feasible_without_a_rollout(bench):
    rng = np.random.default_rng(4)
    wild = bench.theta0 + 3.0 * rng.normal(size=(16, bench.theta0.size))
    assert not bench.task.feasible(wild).all()
    guarded, moved = bench.guarded(wild, np.tile(bench.theta0, (16, 1)))
    assert moved == int((~bench.task.feasible(wild)).sum()) > 0
    assert bench.task.feasible(guarded).all()


def test_a_guarded_contextual_search_only_throws_feasible_thetas_and_counts_the_pulled_back(bench):
    bounds = bench.task.bounds
    box = ContextBox(np.array(bounds.low), np.array(bounds.high))
    policy = GuardedPolicy(CREPS(bench.theta0, 2.0, seed=3, context_box=box), bench)
    contexts = np.random.default_rng(5).uniform(bounds.low, bounds.high, size=(policy.batch_size, 2))
    thetas = policy.ask(contexts)
    assert bench.task.feasible(thetas).all() and policy.proposals_pulled_back > 0
    assert bench.task.feasible(policy.policy_mean(contexts)).all()


def test_the_validation_targets_are_held_out_and_half_on_the_box_edges(bench):
    bounds = bench.task.bounds
    targets = validation_targets(bounds, 8)
    assert targets.shape == (16, 2)
    assert np.all(targets >= bounds.low) and np.all(targets <= bounds.high)
    on_edge = np.isclose(targets, bounds.low).any(axis=1) | np.isclose(targets, bounds.high).any(axis=1)
    assert not on_edge[:8].any() and on_edge[8:].all()
    for side in (bounds.low, bounds.high):  # every edge of the box has some
        for axis in range(2):
            assert np.isclose(targets[8:, axis], side[axis]).any()
    grid = ThrowingBench(ExperimentConfig(), progress=False).grid
    assert np.min(np.linalg.norm(targets[:, None] - grid[None], axis=2)) > 1e-6
