"""Refining a sequence of blocks for the whole task's cost against block by block: credit assignment on a
toy two-block sequence whose first block must give up some of its own cost for the second."""

import numpy as np
import pytest

from besman.learning.policy_search import WarmStart
from besman.learning.sequences import refine_sequence
from besman.skills.errors import InputError

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
