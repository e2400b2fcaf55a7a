"""Refining a sequence of blocks for the whole task's cost against block by block: credit assignment on a
toy two-block sequence whose first block must give up some of its own cost for the second."""

import numpy as np
import pytest

from besman.core.errors import InputError
from besman.learning.search.hierarchical import refine_sequence
from besman.learning.search.policy_search import WarmStart

GOAL = np.array([1.0, 1.0])  # where the second block would have the first end


def two_blocks(thetas):
    """Block 1 ends at a and costs |a|^2 (it would rather not move); block 2 starts where block 1 ended and
    costs 4 |a - GOAL|^2 + |b - a|^2. The whole task is best at a = 0.8 GOAL, b = a (total 1.6); a block
    refined for its own cost stays at a = 0 and leaves block 2 at 4 |GOAL|^2 = 8."""
    a, b = thetas
    first = (a**2).sum(axis=1)
    second = 4 * ((a - GOAL) ** 2).sum(axis=1) + ((b - a) ** 2).sum(axis=1)
    return np.column_stack([first, second])


STARTS = [WarmStart(np.zeros(2), 0.3), WarmStart(np.zeros(2), 0.3)]


def test_joint_refinement_gives_up_the_first_blocks_cost_for_the_second():
    joint = refine_sequence(two_blocks, STARTS, budget=600, seed=3)
    alone = refine_sequence(two_blocks, STARTS, jointly=False, budget=600, seed=3)
    assert joint.start_cost == alone.start_cost == pytest.approx(8.0)
    assert joint.cost < 1.7, joint.cost  # the optimum 1.6
    np.testing.assert_allclose(joint.thetas[0], 0.8 * GOAL, atol=0.1)
    assert alone.cost > 7.5, alone.cost  # each block's own optimum: 8
    np.testing.assert_allclose(alone.thetas[0], 0.0, atol=0.1)
    assert joint.rollouts >= 600 and alone.rollouts >= 600


def test_the_same_seed_refines_the_same_way():
    first = refine_sequence(two_blocks, STARTS, budget=60, seed=7)
    again = refine_sequence(two_blocks, STARTS, budget=60, seed=7)
    assert first.costs == again.costs
    assert refine_sequence(two_blocks, STARTS, budget=60, seed=8).costs != first.costs


def test_an_objective_of_the_wrong_shape_or_with_a_nan_is_refused_by_name():
    with pytest.raises(InputError, match=r"costs of shape \(1,\), expected \(1, 2\)"):
        refine_sequence(lambda thetas: np.zeros(1), STARTS, budget=10, seed=0)
    with pytest.raises(InputError, match="NaN"):
        refine_sequence(lambda thetas: np.full((len(thetas[0]), 2), np.nan), STARTS, budget=10, seed=0)
    with pytest.raises(InputError, match="cannot be split over 2 blocks"):
        refine_sequence(two_blocks, STARTS, jointly=False, budget=1, seed=0)


# -- pick and place as a sequence: whole-task rollouts, and besman learn --refinement sequence -------------


def test_a_block_that_did_not_run_gets_the_mean_cost_of_the_block_where_it_ran():
    from besman.learning.pipeline.sequence_refinement import impute
    from besman.sim.block_simulation import Reward

    costs = np.array([[0.2, 0.3, 0.1], [1.2, np.nan, np.nan], [0.4, 0.5, np.nan]])
    filled = impute(costs, Reward())
    np.testing.assert_allclose(filled, [[0.2, 0.3, 0.1], [1.2, 0.4, 0.1], [0.4, 0.5, 0.1]])
    assert impute(np.full((2, 1), np.nan), Reward()).tolist() == [[1.0], [1.0]]  # ran nowhere: a failure


def test_a_refinement_the_task_cannot_do_is_refused_before_any_work():
    from dataclasses import replace

    from besman.learning.pipeline.record import LearnError, LearnSettings
    from besman.tasks import task

    blocks = task("pick-place").building_blocks("aila")
    with pytest.raises(LearnError, match="refinement must be one of blocks, sequence, sequence-by-block"):
        LearnSettings(refinement="jointly").check(blocks)
    with pytest.raises(LearnError, match="has no whole-task rollouts"):
        LearnSettings(refinement="sequence").check(replace(blocks, sequence=None))
    assert "refinement" not in LearnSettings().as_dict(blocks)  # the records of earlier pools still match
    assert LearnSettings(refinement="sequence").as_dict(blocks)["refinement"] == "sequence"


def test_a_whole_task_rollout_costs_each_block_and_its_seed_repeats_it():
    """The committed AILA pool's shapes as they are, one pick-and-place tau: the same rollout seed gives
    the same rollout; each block has its own cost (a failure's block carries the failure, the blocks after
    it did not run)."""
    from pathlib import Path

    from besman.tasks import task
    from besman.tasks.pick_place.sequence import SequenceConfig

    shapes = (
        Path(__file__).resolve().parents[1] / "examples" / "pools" / "pick_place_aila" / "work" / "shapes"
    )
    rollouts = SequenceConfig(
        "aila", tuple(str(shapes / f"{b}.json") for b in ("reach", "carry", "return"))
    ).build()
    theta = np.concatenate(rollouts.start())
    tau = task("pick-place").join(task("pick-place").default_values("aila"))
    outcomes = [rollouts.rollout(theta, np.r_[tau, seed, 0]) for seed in (5, 5, 6)]
    assert outcomes[0].costs == outcomes[1].costs and outcomes[0].message == outcomes[1].message
    for outcome in outcomes:
        costs = np.array(outcome.costs)
        if outcome.success:
            assert np.all((costs > 0) & (costs < 0.5)), costs  # motion costs only
        else:
            failed = ("reach", "carry", "return").index(outcome.failed_block)
            assert costs[failed] >= 1.0 and np.all(np.isnan(costs[failed + 1 :]))
    assert any(outcome.success for outcome in outcomes)
