"""Exploratory whole-task rollouts - the blocks' parameters 0.3 from the shapes, the task's perturbations -
warn of nothing in MuJoCo. With the robots' own ``implicitfast`` integrator a cylinder grasped off-centre
spun up between the pads and diverged in 1 (AILA) and 4 (UR5e) of these 20 ("simulation is unstable");
tabletop worlds integrate with ``implicit`` (:func:`besman.sim.world.tabletop_world`). The suite's fixture
(``tests/conftest.py``) fails the test on any MuJoCo warning."""

from __future__ import annotations

from pathlib import Path

import mujoco
import numpy as np
import pytest

from besman.tasks import task
from besman.tasks.pick_place.sequence import SequenceConfig, SequenceRollouts

POOLS = Path(__file__).resolve().parents[1] / "examples" / "pools"
ROLLOUTS = 20
SPREAD = 0.3  # three times the refinement's default exploration


@pytest.mark.slow
@pytest.mark.parametrize("robot", ["aila", "ur5e"])
def test_exploratory_whole_task_rollouts_warn_of_nothing(robot, mujoco_warnings):
    shapes = POOLS / f"pick_place_{robot}" / "work" / "shapes"
    rollouts = SequenceRollouts(
        SequenceConfig(robot, tuple(str(shapes / f"{block}.json") for block in ("reach", "carry", "return")))
    )
    pick_place = task("pick-place")
    taus = pick_place.spread(robot, ROLLOUTS, 3)
    implicit = mujoco.mjtIntegrator.mjINT_IMPLICIT
    assert rollouts.world(pick_place.split(taus[0])).model.opt.integrator == implicit
    rng = np.random.default_rng(7)
    start = np.concatenate(rollouts.start())
    faults = []
    for index, tau in enumerate(taus):
        outcome = rollouts.rollout(start + rng.normal(0.0, SPREAD, start.shape), np.r_[tau, index, index % 2])
        if "simulation fault" in outcome.message:
            faults.append((index, outcome.message))
    assert faults == [] and mujoco_warnings == []
