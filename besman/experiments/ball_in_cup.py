"""Ball-in-a-cup learned: one string length from the demonstration, then a skill template over the length.

    besman experiment ball-in-cup --out docs/results/ball_in_cup [--quick] [--json]
                                  [--pool examples/pools/ball_in_cup]

The protocol is :mod:`besman.experiments.template_study`'s (held-out lengths, one length from the
demonstration at the held-out lengths nearest 10, 50 and 90 % of the box, K = 10 training lengths of a
chain, the template, zero shot and after <= 10 more rollouts); this task's parts (:data:`STUDY`):

- **Baseline**: the scripted swing (:mod:`besman.tasks.ball_in_cup.baseline`), the same at every length.
- **The chain** runs up the lengths, shortest first (the first from the imitated demonstration).
- **A training evaluation is robust**: the mean reward of three rollouts at tau - :data:`ROBUST_WIDTH`, tau
  and tau + :data:`ROBUST_WIDTH` (clipped to the box), so that a training theta catches over a band of
  lengths, not at one; a search stops above :data:`TRAINING_TARGET` (all three caught).
- **The kernel** is chosen among :data:`KERNELS` (convex mixtures: a swing's outcome is chaotic, and a
  mixture never leaves the training thetas) by leave-one-out; with fewer than 3 tasks, length 0.3 and noise
  0.1. The training tasks are not refined together (an affine policy over the length does not catch).

How the settings were chosen (declared): on seed 0's training lengths and on 50 *development* lengths (a
Latin hypercube with seed 2, disjoint from the held-out set), never on the held-out lengths. Tried: the
robust width 0.005 against 0.01 and a plain (one-length) reward (a theta's band of catching lengths went
from about 1 cm to 2 - 5 cm with 0.005; 0.01 made the template's mixtures catch less), searches run to the
full budget against stopped at the target (82 % against 78 % zero shot on the development lengths, at
four times the training rollouts; stopped kept), a smaller spread from a solved task (0.1: no better), and
the refinement's population 2, 5 and 10 (5 kept, as planned). On the development lengths seed 0's template
caught 78 % zero shot and 98 % after refinement. One diagnostic ran on the held-out lengths before the
development lengths were introduced (which of a pilot's training thetas catch where: they cover every
held-out length, and the nearest one catches at 92 %); no setting was taken from it.
"""

from __future__ import annotations

import numpy as np

from besman.experiments.template_study import Config, Study
from besman.skills.shared_kernel import SharedKernel
from besman.tasks.ball_in_cup.baseline import scripted_baseline
from besman.tasks.ball_in_cup.demonstration import FILE, imitate, load_demonstration

SIGMA = 0.3  # CMA-ES's spread (from the demonstration, from a solved task), and the template's prior
ROBUST_WIDTH = 0.005  # m: a training evaluation is the mean reward at tau - width, tau, tau + width
TRAINING_TARGET = 0.95  # a training search stops at a robust mean reward above this: all three caught
REFINE_POPULATION = 5  # refinement: two CMA-ES generations in 10 rollouts
# The kernels the leave-one-out choice tries, fixed before any run: convex mixtures of training thetas (never
# extrapolating beyond them), long length scales before short (in box widths; ten tasks in the 1-D box lie
# about a tenth of it apart), smoothing before interpolating.
KERNELS = tuple(
    SharedKernel(length_scale, noise, weights="convex")
    for length_scale in (0.6, 0.3, 0.15, 0.075)
    for noise in (0.1, 0.01)
)


def band(tau: np.ndarray, box) -> np.ndarray:
    """The lengths a training evaluation averages over: tau and tau +- ROBUST_WIDTH, within the box."""
    return np.clip(tau + np.array([[-ROBUST_WIDTH], [0.0], [ROBUST_WIDTH]]), box.low[0], box.high[0])


STUDY = Study(
    experiment="ball_in_cup",
    task="ball-in-cup",
    robot="ur5e",
    template="ball_in_cup",
    demonstration=FILE,
    imitate=imitate,
    load_demonstration=load_demonstration,
    baselines=(("scripted_baseline", scripted_baseline),),
    sigma=SIGMA,
    training_target=TRAINING_TARGET,
    neighbourhood=band,
    first=lambda taus: int(np.argmin(taus[:, 0])),  # shortest first: the chain runs up the lengths
    refine_population=REFINE_POPULATION,
    kernels=KERNELS,
    few_tasks_kernel=SharedKernel(0.3, 0.1, weights="convex"),
    config=Config(),
    # A small run for tests (about 30 s): one seed, 4 training tasks, 8 held-out lengths.
    quick=Config(
        seeds=1,
        k=4,
        ks=(2, 4),
        held_out=8,
        training_budget=48,
        refine_budget=10,
        single_seeds=2,
        single_quantiles=(0.1,),
        single_budget=32,
    ),
    tau_label="string length",
    cost_label="distance from the cup's axis at the rim (m)",
)
