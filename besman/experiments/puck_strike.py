"""The puck strike learned: one target from the demonstration, then a skill template over the target.

    besman experiment puck-strike --out docs/results/puck_strike [--quick] [--json]
                                  [--pool examples/pools/puck_strike]

The protocol is :mod:`besman.experiments.template_study`'s (held-out targets, one target from the
demonstration at the held-out targets nearest 10, 50 and 90 % of the box in both coordinates, K = 10
training targets of a chain, the template, zero shot and after <= 10 more rollouts); this task's parts
(:data:`STUDY`):

- **Baselines**: the scripted strike (:mod:`besman.tasks.puck_strike.baseline`: the textbook planner, each
  strike planned for its target) and the same planner calibrated by one strike at the box's middle (a
  planner with one learned number, reported beside it).
- **The chain** starts at the training target nearest where the demonstration's puck comes to rest
  (:data:`DEMONSTRATION_REST`) and grows to the nearest unsolved target.
- **A training evaluation** is the plain reward at the target (the strike's outcome is smooth in theta,
  unlike a swing's: no band is needed); a search stops above :data:`TRAINING_TARGET`, a success with the
  puck within 2.5 cm of the target, half the success radius.
- **The training tasks are refined together**: the chained thetas disagree in theta's null space (a strike
  that sends the puck to the same place can be timed and shaped in many ways), so their mixtures miss (on
  the development targets seed 0's convex and kriging mixtures of the chain succeeded on 24-42 %);
  contextual CMA-ES then refines an affine policy over the training targets from the thetas' least-squares
  fit (:data:`JOINT_SIGMA`, ``joint_budget`` rollouts), and the template keeps the policy (an affine drift,
  :data:`KERNEL`). With fewer than 3 training targets a plain mixture.

How the settings were chosen (declared): on seed 0's training targets and 50 *development* targets (a Latin
hypercube with seed 2), never on the held-out targets (seed 1, the benchmark's). CMA-ES's spread 0.1 is the
benchmark's (chosen there on the middle target); the training target 0.975 was fixed before any run; the
joint refinement's spread 0.03 was the only one tried (the demonstration's neighbourhood: the rest points of
N(theta, 0.03^2) lie a median 3.7 cm apart), and its budget was read off seed 0's development curve (the
policy's mean succeeded on 66, 70, 74, 78, 82, 86, 86, 86, 86, 84 % of the development targets after
800 .. 8000 rollouts: 4800 kept). The refinement's population 5 is ball-in-a-cup's.
"""

from __future__ import annotations

import numpy as np

from besman.experiments.template_study import Config, Study
from besman.skills.shared_kernel import SharedKernel
from besman.tasks.puck_strike.baseline import calibrated_baseline, scripted_baseline
from besman.tasks.puck_strike.demonstration import FILE, imitate, load_demonstration

SIGMA = 0.1  # CMA-ES's spread (from the demonstration, from a solved task), and the template's prior
TRAINING_TARGET = 0.975  # a success within 2.5 cm of the target
JOINT_SIGMA = 0.03  # the joint refinement's start spread
DEMONSTRATION_REST = (1.34, 0.13)  # m: where the imitated demonstration's puck comes to rest
REFINE_POPULATION = 5
KERNEL = SharedKernel(0.6, 0.01, weights="kriging", drift="affine")  # reproduces the affine policy


def nearest_the_demonstration(taus: np.ndarray) -> int:
    return int(np.argmin(np.linalg.norm(taus - np.asarray(DEMONSTRATION_REST), axis=1)))


STUDY = Study(
    experiment="puck_strike",
    task="puck-strike",
    robot="ur5e",
    template="puck_strike",
    demonstration=FILE,
    imitate=imitate,
    load_demonstration=load_demonstration,
    baselines=(("scripted_baseline", scripted_baseline), ("calibrated_baseline", calibrated_baseline)),
    sigma=SIGMA,
    training_target=TRAINING_TARGET,
    neighbourhood=lambda tau, box: tau[None],
    first=nearest_the_demonstration,
    refine_population=REFINE_POPULATION,
    kernels=(KERNEL,),
    few_tasks_kernel=SharedKernel(0.3, 0.1, weights="convex"),
    joint_sigma=JOINT_SIGMA,
    config=Config(ks=(4, 10), joint_budget=4800),
    # A small run for tests: one seed, 4 training targets, 8 held-out targets.
    quick=Config(
        seeds=1,
        k=4,
        ks=(4,),
        held_out=8,
        training_budget=48,
        refine_budget=10,
        single_seeds=2,
        single_quantiles=(0.5,),
        single_budget=32,
        joint_budget=160,
    ),
    tau_label="target",
    cost_label="distance from the target to where the puck comes to rest (m)",
)
