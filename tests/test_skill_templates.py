"""Skill templates (the shared-weight model and its Omega, the per-dimension GPs, exploration covariances),
the kernel chosen by leave-one-out outcomes, the zero-shot baselines, and the template pool on disk."""

import json
import multiprocessing
import textwrap

import numpy as np
import py_trees
import pytest
from helpers import run_cli
from sklearn.gaussian_process import GaussianProcessRegressor

from besman.core.errors import InputError
from besman.learning.template_selection import CANDIDATES, choose_kernel
from besman.sim.executor import Executor
from besman.sim.world import tabletop_world
from besman.skills import DMP, DMPSettings, MovementPrimitive, zero_shot
from besman.skills.pool import PoolError, SkillTemplatePool
from besman.skills.shared_kernel import SharedKernel
from besman.skills.task_bounds import TaskBounds
from besman.skills.template import SkillTemplate
from besman.skills.template_models import leave_one_out_means, per_dimension_kernel
from besman.trees import Runner, load_tree
from besman.trees.blackboard import set_task_values

BOX = TaskBounds(("x", "y"), (-1.0, 0.0), (1.0, 2.0))


SMOOTH = SharedKernel(2.0, 1e-8, weights="kriging")  # interpolates a smooth map


def linear_template(name="reach", k=12, seed=0, **options) -> tuple[SkillTemplate, np.ndarray, np.ndarray]:
    """A template of a 2-D DMP (24 numbers) trained on theta = A tau + b at k random tasks."""
    rng = np.random.default_rng(seed)
    prototype = MovementPrimitive(DMP(2, execution_time=1.0), name)
    slope, offset = rng.normal(size=(2, prototype.theta.size)), rng.normal(size=prototype.theta.size)
    taus = rng.uniform(BOX.low, BOX.high, size=(k, 2))
    if options.get("model", "shared") == "shared":
        options = {"prior_spread": 0.5, "kernel": SMOOTH, **options}
    return SkillTemplate(name, prototype, taus, taus @ slope + offset, BOX, **options), slope, offset


@pytest.mark.parametrize("model", ["shared", "per_dimension"])
def test_a_linear_map_is_recovered_and_the_variance_grows_away_from_the_training_tasks(model):
    template, slope, offset = linear_template(model=model)
    inside = np.array([[0.1, 1.2], [-0.5, 0.5]])
    means, _ = template.predict(inside)
    np.testing.assert_allclose(means, inside @ slope + offset, atol=0.02 * np.abs(slope).max())
    near, far, farther = (template.predict(tau)[1] for tau in ([0.0, 1.0], [3.0, 1.0], [6.0, 1.0]))
    assert np.all(near < far) and np.all(far <= farther)  # every dimension, growing with the distance
    if model == "shared":  # far from every task: the prior exploration
        np.testing.assert_allclose(template.predict([60.0, 1.0])[1], 0.25, rtol=1e-6)
    instance = template.instantiate([0.1, 1.2])
    np.testing.assert_allclose(instance.theta, means[0], rtol=1e-9, atol=1e-9)
    assert instance.provenance["template"] == "reach" and instance.provenance["tau"] == {"x": 0.1, "y": 1.2}
    assert instance is not template.prototype and template.prototype.theta.any() == 0


def test_an_affine_drift_predicts_an_affine_map_exactly_beyond_its_tasks_and_a_constant_one_does_not():
    """Universal kriging: training thetas on an affine function of tau are predicted on it everywhere (a
    contextual search's linear policy kept as a template), whatever the length scale and noise."""
    beyond = np.array([[-1.5, 2.5], [0.3, 0.7], [1.8, -0.4]])  # two of them outside the box
    for length_scale, noise in ((0.6, 0.01), (0.1, 0.5)):
        kernel = SharedKernel(length_scale, noise, weights="kriging", drift="affine")
        template, slope, offset = linear_template(k=5, kernel=kernel)
        np.testing.assert_allclose(template.predict(beyond)[0], beyond @ slope + offset, atol=1e-9)
    constant, slope, offset = linear_template(k=5, kernel=SharedKernel(0.6, 0.01, weights="kriging"))
    assert np.abs(constant.predict(beyond)[0] - (beyond @ slope + offset)).max() > 0.1
    # Omega's leave-one-out residuals need m + 1 tasks without each one: m + 2 = 4 in all.
    with pytest.raises(InputError, match=r"affine drift over 2 task parameters needs .*at least 4.*got 3"):
        linear_template(k=3, kernel=SharedKernel(weights="kriging", drift="affine"))
    with pytest.raises(InputError, match="drift 'affine' needs weights 'kriging'"):
        SharedKernel(drift="affine")
    with pytest.raises(InputError, match="kernel drift must be one of"):
        SharedKernel(drift="quadratic")


def test_a_version_2_entry_has_the_constant_drift_and_a_version_3_entry_its_own(tmp_path):
    pool = SkillTemplatePool(tmp_path)
    affine = SharedKernel(0.6, 0.01, weights="kriging", drift="affine")
    pool.add(linear_template(k=5, kernel=affine)[0])
    assert SkillTemplatePool(tmp_path)["reach"].kernel == affine
    manifest = tmp_path / "reach.json"
    document = json.loads(manifest.read_text())
    assert document["schema_version"] == 3 and document["kernel"]["drift"] == "affine"
    del document["kernel"]["drift"]
    manifest.write_text(json.dumps({**document, "schema_version": 2}))
    assert SkillTemplatePool(tmp_path)["reach"].kernel.drift == "constant"
    manifest.write_text(json.dumps({**document, "schema_version": 3}))
    with pytest.raises(PoolError, match=r"reach\.json: kernel.*drift"):
        SkillTemplatePool(tmp_path)["reach"]


@pytest.mark.filterwarnings("ignore::sklearn.exceptions.ConvergenceWarning")
def test_each_dimension_has_its_own_gp_and_variance_shape():
    """The shared-kernel trap: one GP for all outputs would give every dimension the same variance shape.
    Here a smooth, a noisy and a constant dimension get their own: checked against scikit-learn GPs fitted
    to each dimension alone."""
    rng = np.random.default_rng(1)
    prototype = MovementPrimitive(DMP(1, settings=DMPSettings(n_weights=2)), "p")
    taus = rng.uniform(BOX.low, BOX.high, size=(15, 2))
    thetas = np.column_stack([np.sin(taus[:, 0]), rng.normal(size=15), np.full(15, 2.0), taus[:, 1]])
    template = SkillTemplate("p", prototype, taus, thetas, BOX, model="per_dimension")
    a, b = [0.0, 1.0], [0.9, 1.9]
    (_, variance_a), (_, variance_b) = template.predict(a), template.predict(b)
    ratios = variance_b / variance_a
    assert not np.isclose(ratios[0], ratios[1], rtol=0.2)  # different shapes
    assert variance_a[2] < 1e-6 * variance_a[1]  # a parameter that never changes is (almost) certain
    for j in range(4):
        alone = GaussianProcessRegressor(
            per_dimension_kernel(2), normalize_y=True, n_restarts_optimizer=2, random_state=j
        )
        alone.fit(BOX.normalise(taus), thetas[:, j])
        mean, std = alone.predict(BOX.normalise(np.array([a, b])), return_std=True)
        np.testing.assert_allclose(template.predict(np.array([a, b]))[0][:, j], mean, rtol=1e-6, atol=1e-9)
        np.testing.assert_allclose(
            template.predict(np.array([a, b]))[1][:, j], np.maximum(std**2, 1e-300), rtol=1e-6, atol=1e-12
        )


def test_the_exploration_covariances_are_the_documented_ones():
    template, _, _ = linear_template(kernel=SharedKernel(1.0, 0.1, weights="kriging"))
    tau = np.array([0.3, 0.4])
    mean, variance = template.predict(tau)
    uncertainty_mean, uncertainty = template.distribution(tau)
    np.testing.assert_array_equal(uncertainty_mean, mean)
    np.testing.assert_allclose(uncertainty, np.diag(variance))
    _, proportional = template.with_exploration("weight_proportional").distribution(tau)
    typical = np.abs(template.thetas).mean(axis=0)
    assert np.count_nonzero(proportional - np.diag(np.diag(proportional))) == 0
    np.testing.assert_allclose(np.diag(proportional) / typical**2, np.diag(proportional)[0] / typical[0] ** 2)
    assert np.trace(proportional) == pytest.approx(variance.sum())
    _, correlated = template.with_exploration("correlated").distribution(tau)
    np.testing.assert_allclose(np.diag(correlated), variance)
    _, isotropic = template.with_exploration("isotropic").distribution(tau)
    np.testing.assert_allclose(isotropic, np.eye(len(variance)) * variance.mean())
    assert np.linalg.eigvalsh(correlated).min() > -1e-12 * variance.max()
    # theta = A tau + b: the training thetas are perfectly correlated in pairs, and the shrunk estimate keeps
    # a strong correlation where the plain one is +-1.
    strongest = np.abs(correlated / np.sqrt(np.outer(variance, variance)) - np.eye(len(variance))).max()
    assert 0.5 < strongest < 1.0


# -- the shared-weight model ---------------------------------------------------------------------------------


def null_space_problem(k: int, seed: int):
    """Thetas whose outcome depends on 2 of 40 directions, as policy search leaves them: theta_i = the
    minimum-norm solution for target tau_i plus a large random walk in the 38 directions the outcome ignores.
    Returns the template's inputs, the outcome map (2, 40), and a function making training sets."""
    rng = np.random.default_rng(seed)
    outcome = np.linalg.qr(rng.normal(size=(40, 2)))[0].T  # orthonormal rows: the directions that matter
    null = np.eye(40) - outcome.T @ outcome

    def solution(taus):  # a smooth, nonlinear target-to-outcome-coordinates map
        return np.column_stack([np.sin(1.5 * taus[:, 0]) + taus[:, 1], taus[:, 0] * taus[:, 1]])

    taus = rng.uniform(BOX.low, BOX.high, size=(k, 2))
    thetas = solution(taus) @ outcome + 1.5 * rng.normal(size=(k, 40)) @ null
    return taus, thetas, outcome, solution


def test_the_shared_weights_recover_a_map_whose_outcome_lies_in_a_few_directions_better_than_per_dimension():
    """The outcome of a combination of whole training thetas is the same combination of their outcomes, so
    the null-space noise cannot spoil it; per-dimension GPs see 40 noisy series and mix coordinates of
    different thetas. Both predict at held-out tasks; the shared model's kernel is chosen by leave-one-out
    outcomes at held-out validation targets (no test task involved)."""
    taus, thetas, outcome, solution = null_space_problem(16, seed=3)
    tests = np.random.default_rng(4).uniform(BOX.low, BOX.high, size=(50, 2))
    validation = np.random.default_rng(5).uniform(BOX.low, BOX.high, size=(8, 2))

    def outcome_error(predicted, at):
        return np.linalg.norm(predicted @ outcome.T - solution(at), axis=1)

    choice = choose_kernel(taus, thetas, BOX, validation, outcome_error)
    assert choice.rollouts == len(CANDIDATES) * len(validation) and len(choice.losses) == len(CANDIDATES)
    assert choice.kernel == CANDIDATES[int(np.argmin(choice.losses))]
    # One task: every candidate predicts its theta, so nothing is thrown.
    assert choose_kernel(taus[:1], thetas[:1], BOX, validation, outcome_error).rollouts == 0
    # No interpolating kriging among the candidates: its weights extrapolate at the box's edges.
    assert not [k for k in CANDIDATES if k.weights == "kriging" and k.noise < 0.1]
    prototype = MovementPrimitive(DMP(4, settings=DMPSettings(n_weights=8)), "p")
    shared = SkillTemplate("p", prototype, taus, thetas, BOX, kernel=choice.kernel, prior_spread=0.3)
    per_dimension = SkillTemplate("p", prototype, taus, thetas, BOX, model="per_dimension")
    shared_error = outcome_error(shared.predict(tests)[0], tests).mean()
    per_dimension_error = outcome_error(per_dimension.predict(tests)[0], tests).mean()
    mean_error = outcome_error(zero_shot.training_mean(None, thetas, tests), tests).mean()
    assert shared_error < 0.5 * per_dimension_error and shared_error < 0.3 * mean_error


def test_shared_weights_sum_to_one_and_leave_one_out_is_a_refit_without_the_task():
    taus, thetas, _, _ = null_space_problem(7, seed=5)
    prototype = MovementPrimitive(DMP(4, settings=DMPSettings(n_weights=8)), "p")
    for kernel in (SharedKernel(0.4, 0.05, weights="kriging"), SharedKernel(0.4, 0.05, weights="convex")):
        template = SkillTemplate("p", prototype, taus, thetas, BOX, kernel=kernel, prior_spread=0.3)
        weights, remote = template.model.weights(BOX.normalise(np.array([[0.2, 0.7], [5.0, 9.0]])))
        np.testing.assert_allclose(weights.sum(axis=1), 1.0)
        assert remote[1] == pytest.approx(1.0) and 0 <= remote[0] < 1
        if kernel.weights == "convex":
            assert weights.min() >= 0
        # A constant coordinate is predicted exactly anywhere.
        constant = thetas.copy()
        constant[:, 0] = 2.5
        refit = SkillTemplate("p", prototype, taus, constant, BOX, kernel=kernel, prior_spread=0.3)
        np.testing.assert_allclose(refit.predict([7.0, -3.0])[0][0], 2.5)
        loo = leave_one_out_means(BOX.normalise(taus), thetas, kernel)
        alone = SkillTemplate("p", prototype, taus[1:], thetas[1:], BOX, kernel=kernel, prior_spread=0.3)
        np.testing.assert_allclose(loo[0], alone.predict(taus[0])[0])


def test_omega_falls_back_to_the_prior_exploration_at_one_task_and_far_from_the_data():
    prototype = MovementPrimitive(DMP(2, execution_time=1.0), "p")
    spread = np.linspace(0.1, 0.5, prototype.theta.size)
    one = SkillTemplate(
        "p", prototype, [[0.3, 1.1]], np.ones((1, prototype.theta.size)), BOX, prior_spread=spread
    )
    for tau in ([0.3, 1.1], [0.9, 0.2], [50.0, 50.0]):
        mean, covariance = one.distribution(np.array(tau))
        np.testing.assert_allclose(mean, 1.0)
        np.testing.assert_allclose(covariance, np.diag(spread**2))
    # Many tasks: near them the spread is what the tasks disagree about, far away the prior again.
    taus, thetas, _, _ = null_space_problem(12, seed=6)
    prototype = MovementPrimitive(DMP(4, settings=DMPSettings(n_weights=8)), "p")
    many = SkillTemplate("p", prototype, taus, thetas, BOX, kernel=SharedKernel(0.3, 0.01), prior_spread=0.05)
    residual = ((thetas - leave_one_out_means(BOX.normalise(taus), thetas, many.kernel)) ** 2).mean(axis=0)
    expected = (2 * 0.05**2 + 11 * residual) / (2 + 11)  # nu0 = 2 prior tasks, K - 1 = 11 residual ones
    np.testing.assert_allclose(many.model.residual_variance, expected)
    near = many.predict(taus[0])[1]
    assert np.all(near > 0.05**2) and np.allclose(many.predict([100.0, 100.0])[1], 0.05**2)


def test_the_zero_shot_baselines_follow_their_definitions():
    rng = np.random.default_rng(8)
    inputs, queries = rng.uniform(size=(6, 2)), rng.uniform(size=(4, 2))
    affine = 1.0 + inputs @ np.array([[2.0, -1.0, 0.5], [0.0, 3.0, 1.0]])
    np.testing.assert_allclose(
        zero_shot.affine_regression(inputs, affine, queries),
        1.0 + queries @ np.array([[2.0, -1.0, 0.5], [0.0, 3.0, 1.0]]),
    )
    thetas = rng.normal(size=(6, 3))
    nearest = zero_shot.nearest_neighbour(inputs, thetas, inputs[[3, 1]] + 1e-6)
    np.testing.assert_array_equal(nearest, thetas[[3, 1]])
    np.testing.assert_allclose(
        zero_shot.training_mean(inputs, thetas, queries), np.tile(thetas.mean(0), (4, 1))
    )
    # CrKR: a task with a tiny reward hardly counts; with equal rewards it is kernel ridge regression.
    rewards = np.ones(6)
    gram = np.exp(-0.5 * ((inputs[:, None] - inputs[None]) ** 2).sum(2) / 0.6**2)
    cross = np.exp(-0.5 * ((queries[:, None] - inputs[None]) ** 2).sum(2) / 0.6**2)
    centre = thetas.mean(0)
    ridge = centre + cross @ np.linalg.solve(gram + 0.5 * np.eye(6), thetas - centre)
    np.testing.assert_allclose(zero_shot.crkr(inputs, thetas, queries, rewards), ridge)
    distrusted = rewards.copy()
    distrusted[2] = 1e-3
    at_task = inputs[2:3]
    trusted_gap = np.abs(zero_shot.crkr(inputs, thetas, at_task, rewards) - thetas[2]).sum()
    assert np.abs(zero_shot.crkr(inputs, thetas, at_task, distrusted) - thetas[2]).sum() > 2 * trusted_gap
    # The outcome template: the theta whose own outcome is nearest, wherever its training task was.
    outcomes = rng.uniform(size=(6, 2))
    np.testing.assert_array_equal(
        zero_shot.nearest_outcome(outcomes, thetas, outcomes[[5, 0]] + 1e-6), thetas[[5, 0]]
    )


def test_bad_template_input_is_refused_by_name():
    prototype = MovementPrimitive(DMP(2), "p")
    with pytest.raises(InputError, match="exploration must be one of"):
        SkillTemplate("p", prototype, [[0.0, 1.0]], np.zeros((1, 24)), BOX, exploration="wide")
    with pytest.raises(InputError, match="thetas have 5 entries"):
        SkillTemplate("p", prototype, [[0.0, 1.0]], np.zeros((1, 5)), BOX)
    with pytest.raises(InputError, match="taus"):
        SkillTemplate("p", prototype, [[0.0, np.nan]], np.zeros((1, 24)), BOX)
    with pytest.raises(InputError, match="model must be one of"):
        SkillTemplate("p", prototype, [[0.0, 1.0]], np.zeros((1, 24)), BOX, model="gp", prior_spread=0.1)
    with pytest.raises(InputError, match="needs prior_spread"):
        SkillTemplate("p", prototype, [[0.0, 1.0]], np.zeros((1, 24)), BOX)
    with pytest.raises(InputError, match="prior_spread must be one standard deviation >= 0 or 24"):
        SkillTemplate("p", prototype, [[0.0, 1.0]], np.zeros((1, 24)), BOX, prior_spread=[0.1, 0.2])
    with pytest.raises(InputError, match="kernel length_scale must be a positive number"):
        SharedKernel(length_scale=0.0)
    with pytest.raises(InputError, match="kernel weights must be one of"):
        SharedKernel(weights="softmax")
    template = unfitted("p", 0)
    with pytest.raises(InputError, match="tau must have 2 entries"):
        template.instantiate([1.0, 2.0, 3.0])


# -- the pool -----------------------------------------------------------------------------------------------


@pytest.mark.slow
def test_a_pool_round_trips_templates_exactly(tmp_path):
    pool = SkillTemplatePool(tmp_path / "pool")
    for model in ("per_dimension", "shared"):
        template, _, _ = linear_template(
            exploration="correlated", provenance={"learner": "test"}, model=model
        )
        pool.add(template, overwrite=True)
        loaded = SkillTemplatePool(tmp_path / "pool")["reach"]
        taus = np.array([[0.2, 0.3], [4.0, -2.0]])
        for got, want in zip(loaded.predict(taus), template.predict(taus), strict=True):
            np.testing.assert_array_equal(got, want)
        np.testing.assert_array_equal(loaded.distribution(taus[0])[1], template.distribution(taus[0])[1])
        assert (loaded.exploration, loaded.provenance, loaded.box) == ("correlated", {"learner": "test"}, BOX)
        assert (loaded.model.name, loaded.kernel) == (model, template.kernel)
    assert list(pool) == ["reach"] and len(pool) == 1 and "reach" in pool and "other" not in pool
    with pytest.raises(PoolError, match="already has 'reach'"):
        pool.add(template)
    pool.add(linear_template(seed=4)[0], overwrite=True)
    assert not np.array_equal(pool["reach"].thetas, template.thetas)  # the cache sees the new entry
    assert not any(path.name.endswith(".tmp") for path in (tmp_path / "pool").iterdir())
    pool.remove("reach")
    assert list(pool) == []


def unfitted(name: str, seed: int) -> SkillTemplate:
    """A template with nothing to fit (the shared model): quick to make."""
    return linear_template(name=name, k=4, seed=seed)[0]


def test_a_version_1_entry_is_read_as_the_per_dimension_template_it_is(tmp_path):
    """Pools written before the model was stored (schema version 1) hold per-dimension templates."""
    pool = SkillTemplatePool(tmp_path)
    template = linear_template(k=4, model="per_dimension", hyperparameters=np.zeros((24, 4)))[0]
    pool.add(template)
    manifest = tmp_path / "reach.json"
    document = json.loads(manifest.read_text())
    del document["kernel"]["model"]
    manifest.write_text(json.dumps({**document, "schema_version": 1}))
    loaded = SkillTemplatePool(tmp_path)["reach"]
    assert loaded.model.name == "per_dimension"
    np.testing.assert_array_equal(loaded.predict([0.1, 0.2])[0], template.predict([0.1, 0.2])[0])
    # A version-1 manifest over a shared template's arrays lacks the GPs' hyperparameters: refused by name.
    pool.add(unfitted("shared", 1))
    shared = tmp_path / "shared.json"
    shared.write_text(json.dumps({**json.loads(shared.read_text()), "schema_version": 1}))
    with pytest.raises(PoolError, match=r"shared\.json: the arrays lack 'hyperparameters'"):
        SkillTemplatePool(tmp_path)["shared"]


def _write_templates(directory, seed, count):
    pool = SkillTemplatePool(directory)
    for i in range(count):
        pool.add(unfitted(f"w{seed}_{i % 3}", seed), overwrite=True)
        pool.add(unfitted("shared", seed), overwrite=True)


@pytest.mark.slow
def test_two_writers_at_once_leave_a_readable_pool(tmp_path):
    context = multiprocessing.get_context("spawn")
    writers = [context.Process(target=_write_templates, args=(tmp_path, seed, 6)) for seed in (1, 2)]
    for writer in writers:
        writer.start()
    for writer in writers:
        writer.join(timeout=120)
        assert writer.exitcode == 0
    pool = SkillTemplatePool(tmp_path)
    assert sorted(pool) == sorted(["shared", *(f"w{s}_{i}" for s in (1, 2) for i in range(3))])
    assert pool.problems() == {}
    # The last write wins whole: the shared entry is one writer's template, arrays and manifest together.
    shared = pool["shared"]
    assert any(np.array_equal(shared.thetas, unfitted("shared", s).thetas) for s in (1, 2))


def _corrupt(directory, how):
    manifest, arrays = directory / "bad.json", directory / "bad.npz"
    if how == "truncated arrays":
        arrays.write_bytes(arrays.read_bytes()[:100])
    elif how == "truncated manifest":
        manifest.write_text(manifest.read_text()[:50])
    elif how == "tampered arrays":
        data = dict(np.load(arrays))
        data["thetas"] = data["thetas"] + 1.0
        np.savez(arrays, **data)
    elif how == "wrong version":
        document = json.loads(manifest.read_text())
        manifest.write_text(json.dumps({**document, "schema_version": 99}))
    elif how == "foreign":
        MovementPrimitive(DMP(2), "bad").save(manifest)
    elif how == "renamed":
        document = json.loads(manifest.read_text())
        manifest.write_text(json.dumps({**document, "name": "other"}))


@pytest.mark.parametrize(
    ("how", "message"),
    [
        ("truncated arrays", "checksum does not match"),
        ("truncated manifest", "not valid JSON"),
        ("tampered arrays", "checksum does not match"),
        ("wrong version", "schema_version 99 is not supported"),
        ("foreign", "not a skill template"),
        ("renamed", "the manifest names 'other'"),
    ],
)
def test_a_damaged_entry_is_refused_by_name_and_the_others_stay_readable(tmp_path, how, message):
    pool = SkillTemplatePool(tmp_path)
    pool.add(unfitted("good", 1))
    pool.add(unfitted("bad", 2))
    _corrupt(tmp_path, how)
    fresh = SkillTemplatePool(tmp_path)
    with pytest.raises(PoolError, match=message) as error:
        fresh["bad"]
    assert "bad.json" in str(error.value) or "bad.npz" in str(error.value)
    assert fresh["good"].name == "good"
    assert list(fresh.problems()) == ["bad"]


def test_the_pool_commands_list_and_show(tmp_path, capsys):
    pool = SkillTemplatePool(tmp_path / "pool")
    pool.add(linear_template(k=4, task="reach/test")[0])
    pool.add(unfitted("broken", 3))
    (tmp_path / "pool" / "broken.npz").write_bytes(b"nothing")
    code, out, _ = run_cli(capsys, "pool", "ls", str(tmp_path / "pool"))
    assert code == 1  # one entry is unreadable
    lines = out.splitlines()
    assert lines[0].startswith("broken\tunreadable:") and "broken.npz" in lines[0]
    assert lines[1] == "reach\treach/test\tK=4\ttheta 24\ttau x [-1, 1], y [0, 2]"
    code, out, _ = run_cli(capsys, "pool", "show", str(tmp_path / "pool"), "reach", "--json")
    facts = json.loads(out)
    assert code == 0 and facts["training_tasks"] == 4 and facts["tau"] == {"x": [-1.0, 1.0], "y": [0.0, 2.0]}
    code, _, err = run_cli(capsys, "pool", "show", str(tmp_path / "pool"), "wave")
    assert code == 2 and "no template 'wave' (has: broken, reach)" in err
    code, _, err = run_cli(capsys, "pool", "ls", str(tmp_path / "nowhere"))
    assert code == 2 and "no such pool directory" in err


@pytest.mark.slow
def test_a_tree_file_names_a_pool_whose_template_drives_aila(tmp_path):
    """A template trained on goal shifts of AILA's home pose, stored in a pool directory that a tree file
    names; the tree instantiates it for tau = 0.5 and executes the primitive."""
    py_trees.blackboard.Blackboard.clear()
    world = tabletop_world()
    world.place_on("box", "table", 0.55, -0.08)
    executor = Executor(world)
    home = executor.position.copy()
    shift = np.array([0.3, -0.3, -0.3, 0.5, -0.5, 0.4, 0.3, 0.4])
    taus = np.linspace(0.0, 1.0, 5)[:, None]
    primitives = [
        MovementPrimitive(DMP(8, execution_time=1.0, start=home, goal=home + t * shift), "shift")
        for t in taus[:, 0]
    ]
    template = SkillTemplate(
        "shift",
        primitives[0],
        taus,
        np.array([p.theta for p in primitives]),
        TaskBounds(("s",), (0.0,), (1.0,)),
        kernel=SMOOTH,
        prior_spread=0.1,
    )
    SkillTemplatePool(tmp_path / "skills").add(template)
    (tmp_path / "shift.yaml").write_text(
        textwrap.dedent("""
        besman_tree: 1
        root:
          Sequence:
            name: templated
            children:
              - InstantiateSkillTemplate:
                  name: instantiate
                  pool: skills
                  template_name: shift
                  namespace: shift
                  remap: {tau: /task/shift}
              - ExecutePrimitive: {name: execute, namespace: shift}
        """)
    )
    set_task_values({"shift": [0.5]})
    result = Runner(load_tree(tmp_path / "shift.yaml"), executor).run()
    assert result.status == "SUCCESS", result.message
    np.testing.assert_allclose(executor.measured_position(), home + 0.5 * shift, atol=0.01)
