"""Contextual policy search: C-REPS and contextual CMA-ES on a contextual quadratic, their updates checked
against independent computations, and the driver's rollout budget and checkpoints."""

import math

import numpy as np
import pytest

from besman.core.errors import InputError
from besman.learning.search.contextual import (
    CREPS,
    ContextBox,
    ContextualCMAES,
    ContextualCMAESConfig,
    CREPSConfig,
    contextual_population_size,
    contextual_search,
)
from besman.learning.search.linear_gaussian import context_features, solve_creps_dual, weighted_ridge

PARAMETERS, CONTEXT_DIMENSIONS = 5, 2
_problem = np.random.default_rng(0)
SLOPE = _problem.uniform(-1.0, 1.0, (PARAMETERS, CONTEXT_DIMENSIONS))
OFFSET = _problem.uniform(-1.0, 1.0, PARAMETERS)
UNIT_BOX = ContextBox(np.zeros(CONTEXT_DIMENSIONS), np.ones(CONTEXT_DIMENSIONS))
GRID = np.stack(np.meshgrid(np.linspace(0, 1, 5), np.linspace(0, 1, 5)), axis=-1).reshape(-1, 2)


def optimum(contexts):
    """theta*(s) = B s + c."""
    return contexts @ SLOPE.T + OFFSET


def quadratic(thetas, contexts):
    """Reward: minus the squared distance to theta*(s) (maximum 0)."""
    return -np.sum((thetas - optimum(contexts)) ** 2, axis=1)


def quadratic_with_failures(thetas, contexts):
    """As :func:`quadratic`, but farther than 3 from theta*(s) a throw 'fails' with a huge penalty, still
    decreasing with the distance (about 40 % of the first rollouts fail)."""
    squared = -quadratic(thetas, contexts)
    return np.where(squared < 9.0, -squared, -1e9 * (1.0 + squared))


def uniform_contexts(rng, count):
    return rng.uniform(0.0, 1.0, (count, CONTEXT_DIMENSIONS))


def grid_error(optimizer):
    """The policy mean's mean distance to theta*(s) over a 5 x 5 grid of contexts."""
    return float(np.mean(np.linalg.norm(optimizer.policy_mean(GRID) - optimum(GRID), axis=1)))


# C-REPS with BOLeRo's update every 25 rollouts shrinks its exploration ~20 % per update and stalls at 15-60 %
# of the initial error here; an update per 100 fresh rollouts converges (see the module docstring).
SOLVERS = {
    "creps": lambda seed: CREPS(
        np.zeros(PARAMETERS), 1.0, seed=seed, context_box=UNIT_BOX, config=CREPSConfig(update_every=100)
    ),
    "contextual_cmaes": lambda seed: ContextualCMAES(
        np.zeros(PARAMETERS), 1.0, seed=seed, context_box=UNIT_BOX
    ),
}


@pytest.mark.parametrize("objective", [quadratic, quadratic_with_failures])
@pytest.mark.parametrize("method", sorted(SOLVERS))
def test_both_methods_learn_the_linear_map_from_contexts_to_the_optimum(method, objective):
    # The start (theta = 0 everywhere) is 2.75 from theta*(s) on average; the best policy that ignores the
    # context (theta*(0.5, 0.5) everywhere) is 0.64 away. The bound, a tenth of that, needs the map learned.
    initial = np.mean(np.linalg.norm(optimum(GRID), axis=1))
    context_free = np.mean(np.linalg.norm(optimum(np.full((1, 2), 0.5)) - optimum(GRID), axis=1))
    assert initial == pytest.approx(2.750, abs=1e-3) and context_free == pytest.approx(0.641, abs=1e-3)
    for seed in (0, 1):
        optimizer = SOLVERS[method](seed)
        assert grid_error(optimizer) == pytest.approx(initial)
        contextual_search(objective, optimizer, budget=2000, sample_contexts=uniform_contexts, seed=seed)
        assert grid_error(optimizer) < 0.1 * context_free


@pytest.mark.parametrize("method", sorted(SOLVERS))
def test_the_same_seed_repeats_the_search_and_another_seed_does_not(method):
    def search(seed):
        optimizer = SOLVERS[method](seed)
        result = contextual_search(
            quadratic, optimizer, budget=300, sample_contexts=uniform_contexts, seed=seed
        )
        return result, optimizer.policy_mean(GRID)

    (first, policy), (again, policy_again), (other, _) = search(3), search(3), search(4)
    np.testing.assert_array_equal(first.rewards, again.rewards)
    np.testing.assert_array_equal(first.contexts, again.contexts)
    np.testing.assert_array_equal(policy, policy_again)
    assert not np.array_equal(first.rewards, other.rewards)


@pytest.mark.parametrize("method", [CREPS, ContextualCMAES])
def test_the_first_samples_follow_the_start_distribution_in_every_context(method):
    mean, stds = np.arange(5.0), np.array([0.1, 0.5, 1.0, 2.0, 4.0])
    optimizer = method(mean, stds, seed=0, context_dimensions=2)
    contexts = np.random.default_rng(1).uniform(-5, 5, (20_000, 2))
    np.testing.assert_array_equal(optimizer.policy_mean(contexts[:3]), np.tile(mean, (3, 1)))
    thetas = optimizer.ask(contexts)
    assert np.all(np.abs(thetas.mean(axis=0) - mean) < 4 * stds / math.sqrt(20_000))
    np.testing.assert_allclose(thetas.std(axis=0), stds, rtol=0.03)
    np.testing.assert_allclose(optimizer.covariance, np.diag(stds**2), rtol=1e-12, atol=1e-12)


@pytest.mark.parametrize("method", [CREPS, ContextualCMAES])
def test_a_search_can_start_from_a_given_affine_policy(method):
    """The start policy W^T (e.g. a fit of thetas learned task by task) instead of the constant one."""
    box = ContextBox(np.array([10.0, -1.0]), np.array([20.0, 1.0]))
    coefficients = np.random.default_rng(3).normal(size=(3, 5))
    optimizer = method(coefficients[0], 0.1, seed=0, context_box=box, coefficients=coefficients)
    contexts = np.array([[10.0, -1.0], [20.0, 1.0], [12.5, 0.0]])
    expected = np.hstack([np.ones((3, 1)), box.normalise(contexts)]) @ coefficients
    np.testing.assert_allclose(optimizer.policy_mean(contexts), expected, rtol=1e-12, atol=1e-12)
    with pytest.raises(InputError, match="coefficients"):
        method(coefficients[0], 0.1, seed=0, context_box=box, coefficients=coefficients[:2])


def test_contextual_cmaes_ranks_so_monotone_reward_transforms_change_nothing():
    # quadratic_with_failures is a strictly increasing function of quadratic's reward: identical ranks, so the
    # rank baseline gives the identical search, huge penalties or not.
    policies = []
    for objective in (quadratic, quadratic_with_failures, lambda t, s: -np.log1p(-quadratic(t, s))):
        optimizer = SOLVERS["contextual_cmaes"](5)
        contextual_search(objective, optimizer, budget=290, sample_contexts=uniform_contexts, seed=5)
        policies.append(optimizer.policy_mean(GRID))
    np.testing.assert_array_equal(policies[0], policies[1])
    np.testing.assert_array_equal(policies[0], policies[2])


def test_the_context_box_normalises_contexts():
    # The same rollouts in contexts mapped affinely to another box give the same search.
    box = ContextBox(np.array([10.0, -1.0]), np.array([20.0, 1.0]))

    def stretched(contexts):
        return box.low + contexts * (box.high - box.low)

    unit = CREPS(np.zeros(PARAMETERS), 1.0, seed=2, context_box=UNIT_BOX)
    other = CREPS(np.zeros(PARAMETERS), 1.0, seed=2, context_box=box)
    rng = np.random.default_rng(0)
    for _ in range(4):
        contexts = uniform_contexts(rng, unit.batch_size)
        thetas = unit.ask(contexts)
        np.testing.assert_allclose(other.ask(stretched(contexts)), thetas, atol=1e-12)
        unit.tell(contexts, thetas, quadratic(thetas, contexts))
        other.tell(stretched(contexts), thetas, quadratic(thetas, contexts))
    assert unit.updates == other.updates == 4
    np.testing.assert_allclose(other.policy_mean(stretched(GRID)), unit.policy_mean(GRID), atol=1e-9)


def _window(seed=0, count=100):
    """Contexts, thetas around the start and their quadratic rewards."""
    rng = np.random.default_rng(seed)
    contexts = uniform_contexts(rng, count)
    thetas = rng.normal(size=(count, PARAMETERS))
    return contexts, thetas, quadratic(thetas, contexts)


@pytest.mark.parametrize("kind", ["affine", "quadratic"])
def test_the_creps_dual_meets_the_kl_bound_and_keeps_the_context_distribution(kind):
    contexts, _, rewards = _window()
    features = context_features(contexts, kind)
    for epsilon in (0.5, 2.0):
        dual = solve_creps_dual(features, rewards, epsilon)
        weights = dual.weights
        assert weights.sum() == pytest.approx(1.0) and np.all(weights >= 0)
        # KL(reweighted || old rollout distribution) = epsilon: the bound is active at the optimum.
        kl = float(np.sum(weights * np.log(len(weights) * weights)))
        assert kl == pytest.approx(epsilon, abs=1e-3)
        np.testing.assert_allclose(weights @ features, features.mean(axis=0), atol=1e-4)
        # The weights are exp((R - V(s)) / eta), normalised, with the returned eta and baseline.
        expected = np.exp((rewards - features @ dual.baseline) / dual.eta)
        np.testing.assert_allclose(weights, expected / expected.sum(), rtol=1e-6, atol=1e-12)


def test_the_creps_dual_ignores_reward_units_and_context_offsets_and_survives_huge_penalties():
    contexts, _, rewards = _window(1)
    features = context_features(contexts, "affine")
    reference = solve_creps_dual(features, rewards, 2.0).weights
    transformed = 1e6 * rewards - 3e8 + features @ np.array([5.0, -2e7, 4e7])
    np.testing.assert_allclose(solve_creps_dual(features, transformed, 2.0).weights, reference, rtol=1e-3)

    penalised = rewards.copy()
    penalised[::4] = -1e9 * (1.0 + np.arange(25))
    dual = solve_creps_dual(features, penalised, 2.0)
    assert np.all(np.isfinite(dual.weights)) and np.all(dual.weights[::4] < 1e-12)
    positive = dual.weights[dual.weights > 0]
    kl = float(np.sum(positive * np.log(100 * positive)))
    assert kl == pytest.approx(2.0, abs=1e-3)


def test_weighted_ridge_is_least_squares_on_the_weighted_augmented_system():
    rng = np.random.default_rng(2)
    features = context_features(rng.uniform(size=(30, 2)), "quadratic")
    targets = rng.normal(size=(30, 4))
    weights = rng.dirichlet(np.ones(30))
    prior = rng.normal(size=(features.shape[1], 4))
    ridge = 0.05
    # min sum w ||y - f^T B||^2 + ridge ||B - prior||^2 is ordinary least squares on stacked rows.
    design = np.vstack([np.sqrt(weights)[:, None] * features, math.sqrt(ridge) * np.eye(features.shape[1])])
    stacked = np.vstack([np.sqrt(weights)[:, None] * targets, math.sqrt(ridge) * prior])
    expected = np.linalg.lstsq(design, stacked)[0]
    np.testing.assert_allclose(
        weighted_ridge(features, targets, weights, ridge, prior=prior), expected, atol=1e-10
    )
    plain = np.linalg.lstsq(design, np.vstack([stacked[:30], np.zeros_like(prior)]))[0]
    np.testing.assert_allclose(weighted_ridge(features, targets, weights, ridge), plain, atol=1e-10)


def test_a_creps_update_is_the_weighted_maximum_likelihood_fit():
    contexts, _, _ = _window(3, count=25)
    optimizer = CREPS(np.zeros(PARAMETERS), 0.7, seed=0, context_box=UNIT_BOX)
    thetas = optimizer.ask(contexts)
    rewards = quadratic(thetas, contexts)
    optimizer.tell(contexts, thetas, rewards)
    assert optimizer.updates == 1
    weights = optimizer.last_dual.weights
    features = context_features(contexts, "affine")
    np.testing.assert_allclose(weights, solve_creps_dual(features, rewards, 2.0).weights)
    # The mean: weighted least squares of theta on [1, s] with ridge 1e-4 towards the start (zero): ordinary
    # least squares on the weighted rows stacked on 1e-2 I.
    design = np.vstack([np.sqrt(weights)[:, None] * features, 1e-2 * np.eye(3)])
    stacked = np.vstack([np.sqrt(weights)[:, None] * thetas, np.zeros((3, PARAMETERS))])
    coefficients = np.linalg.lstsq(design, stacked)[0]
    grid_features = context_features(GRID, "affine")
    np.testing.assert_allclose(optimizer.policy_mean(GRID), grid_features @ coefficients, atol=1e-10)
    # Sigma: the weighted covariance of the steps from the mean that sampled them (theta = 0), unbiased.
    weighted_mean = weights @ thetas
    unbiased = 1 - weights @ weights
    covariance = np.cov(thetas.T, aweights=weights) + np.outer(weighted_mean, weighted_mean) / unbiased
    np.testing.assert_allclose(optimizer.covariance, covariance, rtol=1e-6, atol=1e-9)


def test_contextual_cmaes_uses_boleros_population_and_updates_once_per_population():
    assert contextual_population_size(96, 2) == 69  # 4 + floor(3 ln 98) * 5
    optimizer = ContextualCMAES(np.zeros(96), 0.3, seed=0, context_dimensions=2)
    assert optimizer.batch_size == optimizer.population_size == 69
    contexts = uniform_contexts(np.random.default_rng(0), 68)
    thetas = optimizer.ask(contexts)
    optimizer.tell(contexts, thetas, -np.sum(thetas**2, axis=1))
    assert optimizer.updates == 0 and optimizer.sigma == pytest.approx(0.3)
    optimizer.tell(contexts[:1], thetas[:1], np.zeros(1))
    assert optimizer.updates == 1


def test_the_driver_spends_exactly_the_budget_and_checkpoints_on_schedule():
    optimizer = SOLVERS["contextual_cmaes"](0)  # population 29
    batches, checkpoints, progress = [], [], []

    def objective(thetas, contexts):
        batches.append(len(thetas))
        return quadratic(thetas, contexts)

    def on_checkpoint(rollouts, seen):
        assert seen is optimizer
        checkpoints.append((rollouts, grid_error(seen)))

    result = contextual_search(
        objective,
        optimizer,
        budget=250,
        sample_contexts=uniform_contexts,
        seed=0,
        checkpoint_every=100,
        on_checkpoint=on_checkpoint,
        progress=progress.append,
    )
    assert result.rollouts == sum(batches) == sum(progress) == 250
    assert result.contexts.shape == (250, 2) and result.rewards.shape == (250,)
    assert [rollouts for rollouts, _ in checkpoints] == result.checkpoints == [0, 100, 200, 250]
    assert max(batches) == 29 and batches[:4] == [29, 29, 29, 13]  # cut at the checkpoint at 100
    assert optimizer.updates == 250 // 29
    assert checkpoints[-1][1] < checkpoints[0][1]
    np.testing.assert_array_equal(result.contexts[:29], uniform_contexts(np.random.default_rng(0), 29))


@pytest.mark.parametrize(
    ("make", "field"),
    [
        (lambda: CREPS([0.0, math.nan], 1.0, seed=0, context_dimensions=1), "mean"),
        (lambda: CREPS(np.zeros(2), -1.0, seed=0, context_dimensions=1), "spread"),
        (lambda: CREPS(np.zeros(2), 1.0, seed=0), "context_dimensions"),
        (lambda: CREPS(np.zeros(2), 1.0, seed=0.5, context_dimensions=1), "seed"),
        (
            lambda: CREPS(np.zeros(2), 1.0, seed=0, context_box=UNIT_BOX, context_dimensions=3),
            "context_dimensions",
        ),
        (lambda: ContextBox([0.0, 1.0], [1.0, 1.0]), "context_box.high"),
        (lambda: ContextBox([0.0, math.inf], [1.0, 2.0]), "context_box.low"),
        (lambda: CREPSConfig(epsilon=0.0), "epsilon"),
        (lambda: CREPSConfig(window=10), "window"),
        (lambda: CREPSConfig(baseline_features="cubic"), "baseline_features"),
        (lambda: ContextualCMAESConfig(population_size=2), "population_size"),
        (lambda: ContextualCMAESConfig(baseline_target="returns"), "baseline_target"),
        (lambda: ContextualCMAES(np.zeros(2), 1.0, seed=0, context_dimensions=0), "context_dimensions"),
    ],
)
def test_bad_settings_are_refused_by_name(make, field):
    with pytest.raises(InputError, match=field.replace(".", r"\.")):
        make()


def test_bad_rollouts_are_refused_by_name():
    optimizer = CREPS(np.zeros(3), 1.0, seed=0, context_dimensions=2)
    contexts = np.zeros((4, 2))
    thetas = optimizer.ask(contexts)
    with pytest.raises(InputError, match="contexts"):
        optimizer.ask(np.zeros((4, 3)))
    with pytest.raises(InputError, match="thetas"):
        optimizer.tell(contexts, thetas[:3], np.zeros(4))
    with pytest.raises(InputError, match="rewards"):
        optimizer.tell(contexts, thetas, [0.0, 0.0, math.nan, 0.0])
    assert optimizer.rollouts_told == 0


def test_the_driver_refuses_bad_budgets_samplers_and_objectives():
    def search(objective=quadratic, sampler=uniform_contexts, **settings):
        optimizer = SOLVERS["creps"](0)
        settings = {"budget": 10, **settings}
        return contextual_search(objective, optimizer, sample_contexts=sampler, seed=0, **settings)

    with pytest.raises(InputError, match="budget"):
        search(budget=0)
    with pytest.raises(InputError, match="checkpoint_every"):
        search(checkpoint_every=0)
    with pytest.raises(InputError, match="sample_contexts"):
        search(sampler=lambda rng, count: rng.uniform(size=count))
    with pytest.raises(InputError, match="objective"):
        search(objective=lambda thetas, contexts: np.zeros(len(thetas) + 1))
    with pytest.raises(InputError, match="objective"):
        search(objective=lambda thetas, contexts: np.full(len(thetas), -math.inf))
