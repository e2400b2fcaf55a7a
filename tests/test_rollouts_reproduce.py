"""Rollouts reproduce bit for bit (issue 54): the same theta, tau and seed give the same outcome, every
measure of it to the last digit, whatever ran before in the process, in which order a batch comes, on the
local worker processes and on Ray. Pick and place's rollouts (its blocks one at a time, and whole perturbed
tasks, its rollout seed in tau) from the committed AILA pool's shapes, at thetas spread as a search's first
generations are; and whole runs of the learned trees of the other manipulation tasks (sort, stack,
handover: their final states included)."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from besman.sim.evaluation import evaluate_on_ray
from besman.tasks import task
from besman.tasks.episodes import EpisodeOutcome, TreeEpisodesConfig
from besman.tasks.pick_place.blocks import BLOCKS, BlockRollouts, BlockTaskConfig
from besman.tasks.pick_place.sequence import SequenceConfig, SequenceRollouts

ROBOT = "aila"
ROOT = Path(__file__).resolve().parents[1]
SHAPES = ROOT / "examples" / "pools" / f"pick_place_{ROBOT}" / "work" / "shapes"
BLOCK_ROLLOUTS, WHOLE_TASKS = 100, 20


def spread(theta: np.ndarray, count: int, rng: np.random.Generator) -> np.ndarray:
    """``count`` thetas about ``theta``, each coordinate off by a third of its size (at least 0.05)."""
    return theta + rng.normal(0.0, 1.0, (count, theta.size)) * np.maximum(np.abs(theta) / 3, 0.05)


def outcomes(evaluation) -> list[str]:
    """Every measure of every rollout, as text that keeps each float's every digit (repr round-trips)."""
    return [
        repr(reward) + repr(detail)
        for reward, detail in zip(evaluation.rewards, evaluation.details, strict=True)
    ]


def here_and_reversed_in_processes(thetas, taus, built) -> tuple[list, list]:
    """The outcomes in order in this process (after whatever ran here before), and of the reversed batch on
    the local worker processes (two, each its half), put back in order."""
    back = slice(None, None, -1)
    here = outcomes(built.evaluate_locally(thetas, taus))
    return here, outcomes(built.evaluate(thetas[back], taus[back]))[back]


@pytest.mark.slow
def test_block_rollouts_reproduce_in_any_order_and_process():
    rng = np.random.default_rng(54)
    entry = task("pick-place")
    counts = np.diff(np.linspace(0, BLOCK_ROLLOUTS, len(BLOCKS) + 1).round().astype(int))
    for block, count in zip(BLOCKS, counts, strict=True):
        config = BlockTaskConfig(block, str(SHAPES / f"{block}.json"), robot=ROBOT)
        built = config.build()
        taus = np.repeat(entry.spread(ROBOT, count // 3 + 1, 54), 3, axis=0)[:count]  # worlds reused
        thetas = spread(built.shape.theta, count, rng)
        first, processes = here_and_reversed_in_processes(thetas, taus, built)
        assert processes == first, block
        assert len(set(first)) == count and isinstance(built, BlockRollouts)  # every rollout its own


@pytest.mark.slow
def test_whole_task_rollouts_reproduce_in_any_order_process_and_on_ray():
    rng = np.random.default_rng(540)
    config = SequenceConfig(ROBOT, tuple(str(SHAPES / f"{block}.json") for block in BLOCKS))
    built = config.build()
    entry = task("pick-place")
    # tau: the task's values, then the rollout's seed (perception errors, the object's mass and friction)
    # and whether it is pushed
    taus = np.c_[
        entry.spread(ROBOT, WHOLE_TASKS, 540), rng.integers(0, 2**31, WHOLE_TASKS), np.arange(20) % 2
    ]
    thetas = spread(np.concatenate(built.start()), WHOLE_TASKS, rng)
    first, processes = here_and_reversed_in_processes(thetas, taus, built)
    assert processes == first
    assert outcomes(built.evaluate(thetas, taus, backend="ray")) == first
    successes = sum("SequenceOutcome(success=True" in outcome for outcome in first)
    assert 0 < successes < WHOLE_TASKS  # the spread reaches both outcomes: a comparison that can differ
    assert isinstance(built, SequenceRollouts)


@pytest.mark.slow
@pytest.mark.parametrize("name", ["sort", "stack", "handover"])
def test_whole_runs_of_the_learned_trees_reproduce_in_any_order_here_and_on_ray(name):
    entry = task(name)
    config = TreeEpisodesConfig(name, str(ROOT / "examples" / "trees" / f"{name}_learned.yaml"), ROBOT)
    rng = np.random.default_rng(541)
    # the task's values as a run draws them (boxes apart), then the run's seed (the slip, the masses)
    taus = np.array([[*entry.draw(ROBOT, rng), rng.integers(0, 2**31)] for _ in range(WHOLE_TASKS)])
    thetas = np.empty((WHOLE_TASKS, 0))
    # in this process, in order; on Ray, reversed, in chunks of three
    first = outcomes(config.build().evaluate_locally(thetas, taus))
    back = slice(None, None, -1)
    on_ray = outcomes(evaluate_on_ray(config, thetas[back], taus[back], chunk_size=3))[back]
    assert on_ray == first
    assert len(set(first)) == WHOLE_TASKS and all(EpisodeOutcome.__name__ in outcome for outcome in first)
    assert all("warnings=()" in outcome for outcome in first)  # none on the Ray workers either
