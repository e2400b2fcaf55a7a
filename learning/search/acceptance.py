"""Whether a refinement improved on its start by more than the reward's noise.

A search keeps the best reward it saw, and with noisy rollouts (perturbations drawn per rollout) the best of
many draws beats the start by luck alone. So the start and the refined theta are evaluated again on the
same ``n`` rollouts (the same perturbation seeds, paired), the **improvement** is the mean reward gained,
and the **noise** is the standard deviation of the start's reward over those repeated evaluations. The
refined theta is accepted only where the improvement exceeds the noise; else the start is kept. Rollouts
that reproduce bit for bit (no perturbations) have noise 0: any gain is accepted, no loss is.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import asdict, dataclass

import numpy as np

from besman.core.errors import InputError


@dataclass(frozen=True)
class Acceptance:
    """A refinement's verdict: ``improvement`` (mean reward gained over the paired evaluations), ``noise``
    (standard deviation of the start's reward over them), ``evaluations`` (how many) and ``accepted``."""

    improvement: float
    noise: float
    evaluations: int
    accepted: bool

    def to_json(self) -> dict:
        return asdict(self)

    def text(self) -> str:
        """The verdict in one phrase, e.g. ``reward gained 0.12, noise 0 over 2 evaluations: kept``."""
        verdict = "kept" if self.accepted else "not kept"
        return (
            f"reward gained {self.improvement:.3g}, noise {self.noise:.3g} over {self.evaluations} "
            f"evaluations: {verdict}"
        )


def judge(start_rewards, refined_rewards) -> Acceptance:
    """The verdict on a refined theta from the start's and its rewards on the same evaluations (paired)."""
    start = np.asarray(start_rewards, dtype=float)
    refined = np.asarray(refined_rewards, dtype=float)
    if start.ndim != 1 or start.shape != refined.shape or len(start) == 0:
        raise InputError(
            f"the start's and the refined theta's rewards must be paired evaluations, got {start.shape} and "
            f"{refined.shape}"
        )
    if not (np.isfinite(start).all() and np.isfinite(refined).all()):
        raise InputError("a reward of the evaluations is not finite: impute failures before judging")
    improvement = float(np.mean(refined - start))
    # Equal rewards have no noise (the std of equal floats can come out 1e-17: their mean is rounded).
    noise = float(np.std(start, ddof=1)) if len(start) > 1 and np.ptp(start) > 0 else 0.0
    return Acceptance(improvement, noise, len(start), improvement > noise)


def reevaluated(
    evaluate: Callable[[np.ndarray], np.ndarray],
    start,
    best,
    repeats: int,
    searched: tuple[float, float] | None = None,
) -> Acceptance:
    """The verdict on a search's ``best`` theta against its ``start``: both evaluated ``repeats`` times more
    in one batch (``evaluate(thetas) -> rewards``, the same rollouts for each), with the search's own
    rewards of them (``searched``: the start's, the best's) as one more paired evaluation if given."""
    again = np.asarray(evaluate(np.repeat([start, best], repeats, axis=0)), dtype=float)
    before, after = ([searched[0]], [searched[1]]) if searched is not None else ([], [])
    return judge([*before, *again[:repeats]], [*after, *again[repeats:]])


def reevaluated_searches(
    evaluate: Callable[[np.ndarray, np.ndarray], np.ndarray], starts, bests, searched, repeats: int
) -> list[Acceptance]:
    """:func:`reevaluated` for many searches in one batch: ``starts`` and ``bests`` (N, n) each evaluated
    ``repeats`` times more, ``evaluate(thetas, owners) -> rewards`` evaluating each theta at the task of
    search ``owners[i]`` (the starts' evaluations first, then the bests'), beside ``searched`` ((start's,
    best's reward) per search)."""
    count = len(starts)
    owners = np.tile(np.repeat(np.arange(count), repeats), 2)
    thetas = np.repeat(np.concatenate([starts, bests]), repeats, axis=0)
    again = np.asarray(evaluate(thetas, owners), dtype=float).reshape(2, count, repeats)
    return [judge([start, *again[0, i]], [best, *again[1, i]]) for i, (start, best) in enumerate(searched)]
