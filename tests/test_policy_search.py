"""Policy search: warm starts, the two optimisers, lockstep search with learning curves."""

import numpy as np
import pytest

from besman.core.errors import InputError
from besman.learning.search.policy_search import (
    CMAES,
    XNES,
    WarmStart,
    default_population_size,
    make_optimizer,
    policy_search,
)

TARGET = np.linspace(-1.0, 1.0, 10)


def sphere(thetas, owners=None):
    """Reward: minus the squared distance to TARGET (maximum 0)."""
    return -np.sum((np.atleast_2d(thetas) - TARGET) ** 2, axis=1)


@pytest.mark.parametrize("method", [CMAES, XNES])
def test_the_first_population_has_the_warm_start_mean_and_spread(method):
    mean, stds = np.arange(5.0), np.array([0.1, 0.5, 1.0, 2.0, 4.0])
    population = method(WarmStart(mean, stds), seed=0, population_size=20_000).ask()
    assert np.all(np.abs(population.mean(axis=0) - mean) < 4 * stds / np.sqrt(20_000))
    np.testing.assert_allclose(population.std(axis=0), stds, rtol=0.03)


@pytest.mark.parametrize("method", [CMAES, XNES])
def test_a_full_covariance_is_honoured_by_whitening(method):
    covariance = np.array([[1.0, 0.8, 0.0], [0.8, 2.0, -0.5], [0.0, -0.5, 0.5]])
    start = WarmStart(np.array([1.0, -2.0, 3.0]), covariance)
    population = method(start, seed=1, population_size=40_000).ask()
    np.testing.assert_allclose(population.mean(axis=0), start.mean, atol=0.03)
    np.testing.assert_allclose(np.cov(population.T), covariance, atol=0.05)


@pytest.mark.parametrize("method", ["cmaes", "xnes"])
def test_both_optimisers_improve_a_simple_task_and_repeat_with_the_seed(method):
    def search(seed):
        optimizer = make_optimizer(method, WarmStart(np.zeros(10), 0.5), seed=seed)
        return policy_search(sphere, [optimizer], budget=600)[0]

    result = search(3)
    start = sphere(np.zeros(10))[0]
    assert result.start_reward == start
    assert result.best_reward > 0.05 * start  # a 20-fold improvement
    assert result.best_reward == pytest.approx(sphere(result.best_theta)[0])
    again = search(3)
    assert again.rewards == result.rewards
    assert search(4).rewards != result.rewards


def test_the_learning_curve_records_every_rollout_and_the_best_so_far():
    optimizer = CMAES(WarmStart(np.zeros(10), 0.5), seed=0)
    result = policy_search(sphere, [optimizer], budget=25)[0]
    size = default_population_size(10)
    assert result.rollouts == size * int(np.ceil(25 / size)) and result.stopped == "budget of 25 rollouts"
    curve = result.curve()
    assert curve.shape == (result.rollouts + 1, 3)
    np.testing.assert_array_equal(curve[:, 0], np.arange(result.rollouts + 1))
    np.testing.assert_array_equal(curve[1:, 1], result.rewards)
    np.testing.assert_array_equal(curve[:, 2], np.maximum.accumulate(curve[:, 1]))
    assert curve[0, 1] == result.start_reward


def test_the_best_within_a_budget_ignores_the_last_generations_overshoot():
    """A search's last generation may pass its budget; the best within the budget is the curve's at it."""
    seen = []

    def later_is_better(thetas, owners):  # each rollout scores its own index: the last one is the best
        seen.extend(thetas)
        return np.arange(len(seen) - len(thetas), len(seen), dtype=float)

    result = policy_search(later_is_better, [CMAES(WarmStart(np.zeros(10), 0.5), seed=0)], budget=12)[0]
    assert result.rollouts == 20 and len(result.thetas) == 20  # two generations of 10
    np.testing.assert_array_equal(result.start_theta, np.zeros(10))
    theta, reward = result.best_within(12)
    assert reward == result.curve()[12, 2] == 12.0 < result.best_reward == 20.0
    np.testing.assert_array_equal(theta, seen[12])
    np.testing.assert_array_equal(result.best_within(0)[0], result.start_theta)
    np.testing.assert_array_equal(result.best_within(20)[0], result.best_theta)


def test_optimisers_run_in_lockstep_with_one_batch_per_generation():
    batches = []

    def objective(thetas, owners):
        batches.append(owners.copy())
        return sphere(thetas) - owners  # each optimiser its own task

    optimizers = [XNES(WarmStart(np.zeros(10), 0.5), seed=s) for s in range(3)]
    results = policy_search(objective, optimizers, budget=20)
    assert batches[0].tolist() == [0, 1, 2]  # the start means
    size = optimizers[0].population_size
    assert all(len(batch) == 3 * size for batch in batches[1:])
    assert [r.rollouts for r in results] == [2 * size] * 3


def test_the_target_reward_stops_a_search_early():
    optimizer = CMAES(WarmStart(TARGET + 0.01, 0.01), seed=0)
    result = policy_search(sphere, [optimizer], budget=1000, target_reward=-0.01)[0]
    assert result.rollouts < 1000 and result.stopped.startswith("reached the target reward")


def test_bad_input_is_refused_by_name():
    with pytest.raises(InputError, match="spread: standard deviations must be > 0"):
        WarmStart(np.zeros(3), [1.0, 0.0, 1.0])
    with pytest.raises(InputError, match="positive definite"):
        WarmStart(np.zeros(2), np.array([[1.0, 2.0], [2.0, 1.0]]))
    with pytest.raises(InputError, match="mean"):
        WarmStart([np.nan, 0.0], 1.0)
    with pytest.raises(InputError, match="method must be one of"):
        make_optimizer("sgd", WarmStart(np.zeros(2), 1.0), seed=0)
    with pytest.raises(InputError, match="NaN or infinite reward"):
        policy_search(
            lambda t, o: np.full(len(t), np.nan), [CMAES(WarmStart(np.zeros(2), 1.0), seed=0)], budget=5
        )
    with pytest.raises(InputError, match="budget"):
        policy_search(sphere, [CMAES(WarmStart(np.zeros(2), 1.0), seed=0)], budget=0)


@pytest.mark.slow
def test_a_search_on_throwing_gives_the_same_curve_on_threads_and_ray():
    """One batch per generation through ThrowingRollouts.evaluate; the backend changes nothing."""
    from besman.tasks.throwing.rollouts import ThrowingRollouts

    task = ThrowingRollouts()
    taus = np.array([[-3.0, -2.0], [-5.0, 0.0]])

    def search(backend):
        optimizers = [CMAES(WarmStart(task.default_theta(), 0.3), seed=s) for s in range(2)]
        objective = lambda thetas, owners: task.evaluate(thetas, taus[owners], backend=backend).rewards  # noqa: E731
        return [result.curve() for result in policy_search(objective, optimizers, budget=34)]

    for threads, ray in zip(search("threads"), search("ray"), strict=True):
        np.testing.assert_array_equal(threads, ray)
        assert threads[-1, 2] > threads[0, 2]  # the best so far improved on the start
