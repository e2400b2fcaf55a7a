"""A refinement is kept only where it beats its start by more than the reward's noise
(:mod:`besman.learning.search.acceptance`)."""

from __future__ import annotations

import numpy as np
import pytest

from besman.core.errors import InputError
from besman.learning.search.acceptance import judge, reevaluated


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
    # Three equal rewards: their mean rounds (np.std gives 1.7e-17 for 0.1 three times), the noise is 0.
    assert judge([0.1, 0.1, 0.1], [0.1, 0.1, 0.1 + 1e-16]).noise == 0.0


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


def test_a_search_is_judged_on_its_start_and_best_evaluated_again_in_one_batch():
    batches = []

    def noisy(thetas):  # the reward is -|theta|, plus a noise that differs between evaluations
        batches.append(len(thetas))
        return -np.abs(thetas[:, 0]) + np.tile([0.0, 0.3], len(thetas) // 2)

    verdict = reevaluated(noisy, np.array([1.0]), np.array([0.9]), 2, searched=(-1.0, -0.6))
    assert batches == [4]  # the start twice, then the best twice
    # start: -1.0 (searched), -1.0, -0.7; best: -0.6 (searched), -0.9, -0.6: gained 0.2, noise 0.17
    assert verdict.evaluations == 3 and verdict.improvement == pytest.approx(0.2)
    assert verdict.noise == pytest.approx(np.std([-1.0, -1.0, -0.7], ddof=1)) and verdict.accepted
    assert not reevaluated(noisy, np.array([1.0]), np.array([0.95]), 2).accepted  # 0.05 inside 0.21
    assert "noise 0.212 over 2 evaluations: not kept" in reevaluated(noisy, [1.0], [0.95], 2).text()
