"""Whether a refinement improved on its start by more than the reward's noise.

A search keeps the best reward it saw, and with noisy rollouts (perturbations drawn per rollout) the best of
many draws beats the start by luck alone. So the start and the refined theta are evaluated again on the
same ``n`` rollouts (the same perturbation seeds, paired), the **improvement** is the mean reward gained,
and the **noise** is the standard deviation of the start's reward over those repeated evaluations. The
refined theta is accepted only where the improvement exceeds the noise; else the start is kept. Rollouts
that reproduce bit for bit (no perturbations) have noise 0: any gain is accepted, no loss is.
"""

from __future__ import annotations

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
    noise = float(np.std(start, ddof=1)) if len(start) > 1 else 0.0
    return Acceptance(improvement, noise, len(start), improvement > noise)
