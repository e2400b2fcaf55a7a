"""Refining a sequence of blocks for the task's whole cost: the credit assignment of hierarchical RL.

A task runs its blocks one after the other (reach, carry, return), each with its own parameters; where one
block ends is where the next starts, so a block's parameters change the cost of every block after it. Two
ways to refine them, on whole-task rollouts (the budget counts those):

- jointly (:func:`refine_sequence`, the default): one optimiser per block, sampled together: rollout i
  runs candidate i of every block, and block k's optimiser is told the cost of block k and of every block
  after it, its cost-to-go (what its parameters can change; the blocks before it are noise to it). This is
  the credit assignment of PI2-Seq (Stulp, Theodorou and Schaal, "Reinforcement learning with sequences of
  motion primitives for robust manipulation", IEEE T-RO 2012), with any optimiser behind
  :class:`~besman.learning.search.policy_search.Optimizer`.
- block by block (``jointly=False``): what refining each block alone amounts to: the blocks one after the
  other, each for its own cost with the others at their current means, the budget split evenly.

``objective(thetas)`` takes per block an (N, n_k) array of parameters and returns the (N, K) costs of the
N rollouts, block by block (lower is better; a failed rollout's blocks from the failure on carry its cost).
"""

from __future__ import annotations

from collections.abc import Callable, Sequence
from dataclasses import dataclass, field

import numpy as np

from besman.core.errors import InputError
from besman.core.seeds import child_seed
from besman.core.validation import CALLABLE, COUNT, SEED, checked, instance, integer, items, optional, text
from besman.learning.search.policy_search import WarmStart, default_population_size, make_optimizer

SequenceObjective = Callable[[list[np.ndarray]], np.ndarray]
"""costs (N, K) of N whole-task rollouts, block by block, for per block its parameters (N, n_k)."""


@dataclass
class SequenceResult:
    """A sequence's refinement.

    Attributes:
        thetas: per block, its search distribution's mean at the end: what the refinement learned (the best
            single rollout would be the luckiest draw of the exploration, not a setting that holds).
        cost: the total cost of a rollout of ``thetas`` after the budget (not counted in it).
        costs: the total cost of every rollout of the budget, in order.
        start_cost: the total cost of the start means, if evaluated (not counted in the budget either).
        stopped: why the refinement ended.
    """

    thetas: list[np.ndarray]
    cost: float
    costs: list[float] = field(default_factory=list)
    start_cost: float | None = None
    stopped: str = ""

    @property
    def rollouts(self) -> int:
        return len(self.costs)


def _cost_matrix(objective: SequenceObjective, thetas: list[np.ndarray]) -> np.ndarray:
    """The objective's (N, K) costs, checked: one row per rollout, one column per block, finite."""
    rows, blocks = len(thetas[0]), len(thetas)
    costs = np.asarray(objective(thetas), dtype=float)
    if costs.shape != (rows, blocks):
        raise InputError(f"the objective returned costs of shape {costs.shape}, expected ({rows}, {blocks})")
    if not np.all(np.isfinite(costs)):
        raise InputError("the objective returned a NaN or infinite cost")
    return costs


def _total(objective: SequenceObjective, means: Sequence[np.ndarray]) -> float:
    """The total cost of one rollout of the blocks' ``means``."""
    return float(_cost_matrix(objective, [np.asarray(mean)[None].copy() for mean in means]).sum())


_ARGUMENTS = {
    "objective": CALLABLE,
    "starts": items(instance(WarmStart, "a WarmStart"), "a list of WarmStarts, one per block"),
    "budget": COUNT,
    "method": text("an optimiser's name"),
    "seed": SEED,
    "population_size": optional(integer(2)),
    "jointly": instance(bool, "True or False"),
    "evaluate_start": instance(bool, "True or False"),
}


@checked(**_ARGUMENTS)
def refine_sequence(
    objective: SequenceObjective,
    starts: Sequence[WarmStart],
    *,
    jointly: bool = True,
    budget: int,
    method: str = "cmaes",
    seed: int,
    population_size: int | None = None,
    evaluate_start: bool = True,
) -> SequenceResult:
    """Refines the blocks, starting from ``starts`` (one per block), ``jointly`` or block by block (see the
    module), for ``budget`` whole-task rollouts (whole
    generations), with ``method`` (an optimiser of
    :func:`~besman.learning.search.policy_search.make_optimizer`) seeded from ``seed`` and the block's index;
    ``population_size`` by default Hansen's for the block (for the largest block where they are sampled
    together). With ``evaluate_start`` the start means' cost is measured first (not counted in the budget)."""
    refine = _refine_jointly if jointly else _refine_block_by_block
    start_cost = _total(objective, [start.mean for start in starts]) if evaluate_start else None
    result = refine(objective, starts, budget, method, seed, population_size)
    result.start_cost = start_cost
    return result


def _refine_jointly(objective, starts, budget, method, seed, population_size) -> SequenceResult:
    """Refines every block together for ``budget`` whole-task rollouts (whole generations), each block's
    optimiser (``method``, seeded from ``seed`` and the block's index) told its cost-to-go. The population
    is shared (rollout i runs candidate i of every block): ``population_size``, by default Hansen's for
    the largest block."""
    size = population_size or max(default_population_size(start.mean.size) for start in starts)
    optimizers = [
        make_optimizer(method, start, seed=child_seed(seed, index), population_size=size)
        for index, start in enumerate(starts)
    ]
    costs: list[float] = []
    while len(costs) < budget:
        thetas = [optimizer.ask() for optimizer in optimizers]
        blocks = _cost_matrix(objective, thetas)
        to_go = np.cumsum(blocks[:, ::-1], axis=1)[:, ::-1]  # block k: its cost and every later block's
        for index, optimizer in enumerate(optimizers):
            optimizer.tell(thetas[index], -to_go[:, index])
        costs.extend(blocks.sum(axis=1).tolist())
    means = [optimizer.mean for optimizer in optimizers]
    return SequenceResult(means, _total(objective, means), costs, stopped=f"budget of {budget} rollouts")


def _refine_block_by_block(objective, starts, budget, method, seed, population_size) -> SequenceResult:
    """Refines the blocks one after the other, first to last, ``budget // K`` whole-task rollouts each
    (whole generations): block k for its own cost alone, the blocks before it at their refined means, those
    after it at their start means."""
    share = budget // len(starts)
    if share == 0:
        raise InputError(f"a budget of {budget} rollouts cannot be split over {len(starts)} blocks")
    means = [start.mean.copy() for start in starts]
    costs: list[float] = []
    for index, start in enumerate(starts):
        size = population_size or default_population_size(start.mean.size)
        optimizer = make_optimizer(method, start, seed=child_seed(seed, index), population_size=size)
        spent = len(costs)
        while len(costs) - spent < share:
            own = optimizer.ask()
            thetas = [np.tile(mean, (len(own), 1)) for mean in means]
            thetas[index] = own
            blocks = _cost_matrix(objective, thetas)
            optimizer.tell(own, -blocks[:, index])
            costs.extend(blocks.sum(axis=1).tolist())
        means[index] = optimizer.mean
    stopped = f"budget of {budget} rollouts, {share} per block"
    return SequenceResult(means, _total(objective, means), costs, stopped=stopped)
