"""Building blocks learned from people in pick and place, reused in tasks they were not learned for: the
template's input (the hand's move), a primitive of the waist and an arm run by the arm alone, a block the
pool does not have refused at setup, and sort, stack and the handover's right arm on the pick-and-place
pool (zero-shot)."""

from pathlib import Path

import numpy as np
import pytest

from besman.core.errors import BesmanError
from besman.sim.block_simulation import INPUT_NAMES, block_input
from besman.sim.executor import Executor
from besman.sim.primitives import on_arm, point_to_point, shaped
from besman.sim.world import tabletop_world
from besman.skills import SkillTemplatePool
from besman.tasks.running import run
from besman.trees import load_tree

ROOT = Path(__file__).resolve().parent.parent
TREES = ROOT / "examples" / "trees"
POOL = ROOT / "examples" / "pools" / "pick_place_aila"


@pytest.fixture(scope="module")
def aila():
    return Executor(tabletop_world(robot="aila")).arm


def test_a_blocks_input_is_the_hands_move_and_its_turn(aila):
    start = aila.home
    goal = start.copy()
    goal[-1] += 0.5  # the last wrist joint turns the hand about its axis
    move = block_input(aila, start, goal)
    begin, end = aila.site_pose(start).position, aila.site_pose(goal).position
    assert move.shape == (len(INPUT_NAMES),)
    np.testing.assert_allclose(move[:3], end - begin, atol=1e-12)
    assert -180.0 <= move[3] < 180.0
    np.testing.assert_allclose(block_input(aila, start, start), 0.0, atol=1e-9)


def test_the_pools_templates_take_the_hands_move():
    pool = SkillTemplatePool(POOL)
    for name in ("reach", "carry", "return"):
        assert tuple(pool[name].box.names) == INPUT_NAMES


def test_a_primitive_of_the_waist_and_an_arm_drives_the_arm_alone(aila):
    world = aila.world
    from besman.sim.arm import Arm

    right = Arm(world, groups=("right_arm",))
    learned = SkillTemplatePool(POOL)["reach"].prototype
    assert learned.dmp.n_dims == aila.dofs == right.dofs + 1
    alone = on_arm(learned, right)
    assert alone.dmp.n_dims == right.dofs and alone.group == right.name
    # The arm's joints keep their learned forcing weights, row for row.
    np.testing.assert_array_equal(alone.dmp.weights, learned.dmp.weights[1:])
    start, goal = right.home, right.home + 0.1
    moved = shaped(learned, "reach", start, goal, right)
    np.testing.assert_allclose(moved.dmp.trajectory().positions[-1], goal, atol=5e-3)
    # The arm's own primitive is left as it is.
    assert on_arm(point_to_point("move", start, goal, right), right).dmp.n_dims == right.dofs


def test_a_tree_asking_the_pool_for_a_block_it_lacks_stops_at_setup_naming_both(tmp_path):
    text = (TREES / "sort_learned.yaml").read_text().replace("grasp_template: reach", "grasp_template: grasp")
    tree = tmp_path / "sort_grasp.yaml"
    tree.write_text(text.replace("../pools/pick_place_{robot}", str(POOL)))
    with pytest.raises(BesmanError) as error:
        load_tree(tree)
    assert "'grasp'" in str(error.value) and str(POOL) in str(error.value)


@pytest.mark.slow
@pytest.mark.parametrize("name", ["sort", "stack", "handover"])
def test_a_task_runs_zero_shot_on_the_pick_and_place_pool(name):
    summary = run(name, TREES / f"{name}_learned.yaml", robot="aila", seed=7)
    assert summary.success, summary.outcome
