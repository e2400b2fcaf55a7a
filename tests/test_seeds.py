"""Every seed the command line accepts (0 .. 2**32 - 1) works in every seeded path, and the same seed gives
the same result."""

import json
import shutil
import subprocess
import sys

import numpy as np
import pytest

from besman.core.errors import InputError
from besman.core.seeds import child_seed, cma_seed
from besman.learning.search.policy_search import CMAES, WarmStart
from besman.skills import DMP, MovementPrimitive
from besman.skills.task_bounds import TaskBounds
from besman.skills.template import SkillTemplate
from besman.skills.template_models import PerDimensionModel, _fit
from besman.tasks import task
from besman.trees import TreeFileError, loads_tree
from tests.test_tree_files import EXAMPLES

TOP = 2**32 - 1  # the largest seed the parser accepts
EXTREMES = (0, TOP)


@pytest.mark.parametrize("seed", EXTREMES)
def test_child_seeds_are_in_range_and_the_same_for_the_same_arguments(seed):
    children = [child_seed(seed, block, task) for block in range(3) for task in range(50)]
    assert all(0 <= child <= TOP for child in children)
    assert children == [child_seed(seed, block, task) for block in range(3) for task in range(50)]
    assert len(set(children)) == len(children)  # other keys, other seeds
    assert child_seed(seed) != child_seed(seed, 0)


@pytest.mark.parametrize("seed", [-1, TOP + 1, 1.5, True, "3"])
def test_a_child_of_no_seed_is_refused(seed):
    with pytest.raises(InputError, match="seed"):
        child_seed(seed, 0)


def test_pycmas_seed_is_never_0_and_stays_the_seed_plus_one_below_the_top():
    assert [cma_seed(s) for s in (0, 1, 41, TOP - 1)] == [1, 2, 42, TOP]  # the searches seeded so far
    assert cma_seed(TOP) == 1  # pycma has one seed fewer (0 draws one at random): the top wraps around


@pytest.mark.parametrize("seed", [*EXTREMES, child_seed(TOP, 2, 7)])
def test_cma_es_runs_with_every_seed_and_repeats_its_samples(seed):
    start = WarmStart(np.zeros(3), 0.1)
    first, again = CMAES(start, seed=seed).ask(), CMAES(start, seed=seed).ask()
    np.testing.assert_array_equal(first, again)
    assert not np.array_equal(first, CMAES(start, seed=seed - 1 if seed else 1).ask())


@pytest.mark.parametrize("seed", EXTREMES)
def test_a_per_dimension_template_fits_with_every_seed_and_repeats(seed):
    rng = np.random.default_rng(0)
    taus, thetas = rng.uniform(size=(4, 2)), rng.normal(size=(4, 3))
    first = PerDimensionModel(taus, thetas, seed=seed).hyperparameters
    np.testing.assert_array_equal(first, PerDimensionModel(taus, thetas, seed=seed).hyperparameters)


def test_a_per_dimension_template_keeps_the_fits_of_the_seeds_used_so_far():
    rng = np.random.default_rng(1)
    taus, thetas = rng.uniform(size=(5, 2)), rng.normal(size=(5, 3))
    kept = [_fit(taus, thetas[:, j], 7 + j).kernel_.theta for j in range(3)]
    np.testing.assert_array_equal(PerDimensionModel(taus, thetas, seed=7).hyperparameters, kept)


def test_a_per_dimension_template_with_the_top_seed_predicts_and_samples_alike():
    rng = np.random.default_rng(2)
    prototype = MovementPrimitive(DMP(1, execution_time=1.0), "t")
    taus, thetas = rng.uniform(size=(4, 2)), rng.normal(size=(4, prototype.theta.size))
    box = TaskBounds(("x", "y"), (0.0, 0.0), (1.0, 1.0))
    template = SkillTemplate("t", prototype, taus, thetas, box, model="per_dimension", seed=TOP)
    assert np.isfinite(template.predict([[0.5, 0.5]])[0]).all()
    np.testing.assert_array_equal(
        template.sample([0.5, 0.5], 3, seed=TOP), template.sample([0.5, 0.5], 3, seed=TOP)
    )


@pytest.mark.parametrize("seed", EXTREMES)
def test_a_tabletop_run_draws_the_same_configuration_for_every_seed(seed):
    pick_place = task("pick-place")
    drawn, again = pick_place.resolve("aila", {}, seed), pick_place.resolve("aila", {}, seed)
    assert drawn.keys() == again.keys() == {"object", "place", "shape", "size"}
    columns = {value.name: len(value.names) for value in pick_place.values}  # 3, 3, 1, 3
    assert all(
        np.array_equal(drawn[name], again[name]) and len(drawn[name]) == columns[name] for name in drawn
    )
    pick_place.bounds("aila").check(pick_place.join(drawn))


@pytest.mark.parametrize(("seed", "ok"), [(0, True), (TOP, True), (-1, False), (TOP + 1, False)])
def test_a_throws_seed_in_a_tree_file_is_checked_with_the_file(seed, ok):
    text = f"besman_tree: 1\nroot:\n  AimThrow: {{name: aim, pool: ../pools/throwing, seed: {seed}}}\n"
    if ok:
        assert loads_tree(text, base=EXAMPLES, source="throw.yaml").seed == seed
        return
    with pytest.raises(TreeFileError, match=rf"throw.yaml:3: root.AimThrow: aim: seed must be .* got {seed}"):
        loads_tree(text, base=EXAMPLES, source="throw.yaml")


@pytest.mark.slow
def test_learn_with_the_largest_seed_writes_a_pool(shared_recordings, tmp_path):
    """The smallest learn (2 recordings, 2 tasks, 1 rollout each; 45 s on 2 cores) with the top seed."""
    demos, out = tmp_path / "demos", tmp_path / "pool"
    demos.mkdir()
    for name in ("subject1_run1.tsv", "subject2_run1.tsv"):
        shutil.copy(shared_recordings / name, demos / name)
    command = [sys.executable, "-m", "besman", "learn", "--demos", str(demos), "--out", str(out)]
    result = subprocess.run(
        [*command, "--training-tasks", "2", "--budget", "1", "--seed", str(TOP)],
        capture_output=True,
        text=True,
    )
    assert result.returncode == 0, result.stderr[-3000:]
    record = json.loads((out / "reach.json").read_text())
    assert record["training"] == {"tasks": 2, "seed": TOP}
