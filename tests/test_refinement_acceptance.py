"""A refinement is kept only where it beats its start by more than the reward's noise
(:mod:`besman.learning.search.acceptance`)."""

from __future__ import annotations

import numpy as np
import pytest

from besman.core.errors import InputError
from besman.learning.search.acceptance import judge


def test_the_noise_is_the_starts_spread_over_repeated_evaluations_and_the_gain_must_exceed_it():
    start = [-1.0, -0.6, -0.8, -1.2]  # std 0.258
    lucky = judge(start, [-0.8, -0.5, -0.7, -1.0])  # gained 0.15 on the same rollouts: inside the noise
    assert lucky.improvement == pytest.approx(0.15) and lucky.noise == pytest.approx(np.std(start, ddof=1))
    assert not lucky.accepted and lucky.evaluations == 4
    better = judge(start, [-0.5, -0.3, -0.5, -0.7])  # gained 0.4 > 0.258
    assert better.accepted and better.to_json() == {
        "improvement": pytest.approx(0.4),
        "noise": pytest.approx(0.2582, abs=1e-4),
        "evaluations": 4,
        "accepted": True,
    }


def test_rollouts_that_reproduce_have_no_noise_any_gain_is_kept_and_no_tie_or_loss():
    assert judge([-0.5, -0.5], [-0.49, -0.49]) == judge([-0.5, -0.5], [-0.49, -0.49])
    assert judge([-0.5, -0.5], [-0.49, -0.49]).accepted
    assert judge([-0.5, -0.5], [-0.49, -0.49]).noise == 0.0
    assert not judge([-0.5, -0.5], [-0.5, -0.5]).accepted
    assert not judge([-0.5, -0.5], [-0.6, -0.6]).accepted
    assert judge([-0.5], [-0.4]).noise == 0.0  # one evaluation: no spread measured


@pytest.mark.parametrize(
    ("start", "refined", "message"),
    [
        ([-1.0, -0.5], [-1.0], "paired"),
        ([], [], "paired"),
        ([[-1.0]], [[-1.0]], "paired"),
        ([-1.0, np.nan], [-1.0, -0.5], "not finite"),
    ],
)
def test_unpaired_or_missing_rewards_are_refused(start, refined, message):
    with pytest.raises(InputError, match=message):
        judge(start, refined)
