"""Skill templates (GP per theta dimension, exploration covariances) and the template pool on disk."""

import json
import multiprocessing
import textwrap

import numpy as np
import py_trees
import pytest
from sklearn.gaussian_process import GaussianProcessRegressor

from besman.sim.executor import Executor
from besman.sim.world import TABLE, tabletop_world
from besman.skills import DMP, DMPSettings, MovementPrimitive
from besman.skills.errors import InputError
from besman.skills.pool import PoolError, SkillTemplatePool
from besman.skills.tasks import TaskBounds
from besman.skills.template import SkillTemplate, default_kernel
from besman.trees import Runner, load_tree
from besman.trees.blackboard import set_task_values
from tests.helpers import run_cli

BOX = TaskBounds(("x", "y"), (-1.0, 0.0), (1.0, 2.0))


def linear_template(name="reach", k=12, seed=0, **options) -> tuple[SkillTemplate, np.ndarray, np.ndarray]:
    """A template of a 2-D DMP (24 numbers) trained on theta = A tau + b at k random tasks."""
    rng = np.random.default_rng(seed)
    prototype = MovementPrimitive(DMP(2, execution_time=1.0), name)
    slope, offset = rng.normal(size=(2, prototype.theta.size)), rng.normal(size=prototype.theta.size)
    taus = rng.uniform(BOX.low, BOX.high, size=(k, 2))
    return SkillTemplate(name, prototype, taus, taus @ slope + offset, BOX, **options), slope, offset


@pytest.mark.slow
def test_a_linear_map_is_recovered_and_the_variance_grows_away_from_the_training_tasks():
    template, slope, offset = linear_template()
    inside = np.array([[0.1, 1.2], [-0.5, 0.5]])
    means, _ = template.predict(inside)
    np.testing.assert_allclose(means, inside @ slope + offset, atol=0.02 * np.abs(slope).max())
    near, far, farther = (template.predict(tau)[1] for tau in ([0.0, 1.0], [3.0, 1.0], [6.0, 1.0]))
    assert np.all(near < far) and np.all(far < farther)  # every dimension, growing with the distance
    instance = template.instantiate([0.1, 1.2])
    np.testing.assert_allclose(instance.theta, means[0], rtol=1e-9, atol=1e-9)
    assert instance.provenance["template"] == "reach" and instance.provenance["tau"] == {"x": 0.1, "y": 1.2}
    assert instance is not template.prototype and template.prototype.theta.any() == 0


@pytest.mark.filterwarnings("ignore::sklearn.exceptions.ConvergenceWarning")
def test_each_dimension_has_its_own_gp_and_variance_shape():
    """The shared-kernel trap: one GP for all outputs would give every dimension the same variance shape.
    Here a smooth, a noisy and a constant dimension get their own: checked against scikit-learn GPs fitted
    to each dimension alone."""
    rng = np.random.default_rng(1)
    prototype = MovementPrimitive(DMP(1, settings=DMPSettings(n_weights=2)), "p")
    taus = rng.uniform(BOX.low, BOX.high, size=(15, 2))
    thetas = np.column_stack([np.sin(taus[:, 0]), rng.normal(size=15), np.full(15, 2.0), taus[:, 1]])
    template = SkillTemplate("p", prototype, taus, thetas, BOX)
    a, b = [0.0, 1.0], [0.9, 1.9]
    (_, variance_a), (_, variance_b) = template.predict(a), template.predict(b)
    ratios = variance_b / variance_a
    assert not np.isclose(ratios[0], ratios[1], rtol=0.2)  # different shapes
    assert variance_a[2] < 1e-6 * variance_a[1]  # a parameter that never changes is (almost) certain
    for j in range(4):
        alone = GaussianProcessRegressor(
            default_kernel(2), normalize_y=True, n_restarts_optimizer=2, random_state=j
        )
        alone.fit(BOX.normalise(taus), thetas[:, j])
        mean, std = alone.predict(BOX.normalise(np.array([a, b])), return_std=True)
        np.testing.assert_allclose(template.predict(np.array([a, b]))[0][:, j], mean, rtol=1e-6, atol=1e-9)
        np.testing.assert_allclose(
            template.predict(np.array([a, b]))[1][:, j], np.maximum(std**2, 1e-300), rtol=1e-6, atol=1e-12
        )


def test_the_exploration_covariances_are_the_documented_ones():
    template, _, _ = linear_template()
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
    assert np.linalg.eigvalsh(correlated).min() > -1e-12 * variance.max()
    # theta = A tau + b: the training thetas are perfectly correlated in pairs, and the shrunk estimate keeps
    # a strong correlation where the plain one is +-1.
    strongest = np.abs(correlated / np.sqrt(np.outer(variance, variance)) - np.eye(len(variance))).max()
    assert 0.5 < strongest < 1.0


def test_bad_template_input_is_refused_by_name():
    prototype = MovementPrimitive(DMP(2), "p")
    with pytest.raises(InputError, match="exploration must be one of"):
        SkillTemplate("p", prototype, [[0.0, 1.0]], np.zeros((1, 24)), BOX, exploration="wide")
    with pytest.raises(InputError, match="thetas have 5 entries"):
        SkillTemplate("p", prototype, [[0.0, 1.0]], np.zeros((1, 5)), BOX)
    with pytest.raises(InputError, match="taus"):
        SkillTemplate("p", prototype, [[0.0, np.nan]], np.zeros((1, 24)), BOX)
    template = unfitted("p", 0)
    with pytest.raises(InputError, match="tau must have 2 entries"):
        template.instantiate([1.0, 2.0, 3.0])


# -- the pool -----------------------------------------------------------------------------------------------


@pytest.mark.slow
def test_a_pool_round_trips_templates_exactly(tmp_path):
    template, _, _ = linear_template(exploration="correlated", provenance={"learner": "test"})
    pool = SkillTemplatePool(tmp_path / "pool")
    pool.add(template)
    loaded = SkillTemplatePool(tmp_path / "pool")["reach"]
    taus = np.array([[0.2, 0.3], [4.0, -2.0]])
    for got, want in zip(loaded.predict(taus), template.predict(taus), strict=True):
        np.testing.assert_array_equal(got, want)
    np.testing.assert_array_equal(loaded.distribution(taus[0])[1], template.distribution(taus[0])[1])
    assert (loaded.exploration, loaded.provenance, loaded.box) == ("correlated", {"learner": "test"}, BOX)
    assert list(pool) == ["reach"] and len(pool) == 1 and "reach" in pool and "other" not in pool
    with pytest.raises(PoolError, match="already has 'reach'"):
        pool.add(template)
    pool.add(linear_template(seed=4)[0], overwrite=True)
    assert not np.array_equal(pool["reach"].thetas, template.thetas)  # the cache sees the new entry
    assert not any(path.name.endswith(".tmp") for path in (tmp_path / "pool").iterdir())
    pool.remove("reach")
    assert list(pool) == []


def unfitted(name: str, seed: int) -> SkillTemplate:
    """A template with given (not fitted) hyperparameters: quick to make."""
    return linear_template(name=name, k=4, seed=seed, hyperparameters=np.zeros((24, 4)))[0]


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
    pool.add(linear_template(k=4, task="reach/test", hyperparameters=np.zeros((24, 4)))[0])
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
    world.place_on("box", TABLE.name, 0.55, -0.08)
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
