"""The acceptance of every demo on every robot it fits (issue 53, "tests by subject"): the task's default
tree succeeds at ten seeded configurations, and every run stays within what the task and the robot declare.

The pairs are derived, not listed: every task of the registry (:data:`besman.tasks.TASKS`) with a default
tree, on every robot of the catalogue (:func:`besman.robots.available`: the shipped ones and those installed
packages bring) and every robot folder of the examples (``examples/robots``: the WidowX AI and the WidowX
pair, brought as a user brings one) that the task fits (:meth:`~besman.tasks.base.Task.fits`). An id is
the task and the robot's name: ``pick-place-ur5e``, ``handover-widowx_ai_pair``.

Each run is checked once, generically, from what the task and the robot declare:

- it succeeds by the task's own rule, and measures what the task says it measures;
- every placement within :data:`~besman.sim.outcomes.PLACE_TOLERANCE` of its target (``placement_error_m``,
  and each of ``placement_errors_m``), a throw within the task's :data:`THROW_TOLERANCE` (``miss_m``); the
  box the sort takes out of the hand is one of the robot's sort boxes (``slipped``);
- a task that measures the arms' contacts (the handover) has no tick with the arms touching and the arms
  never closer than the margin its tree's guards keep (:data:`ARMS_APART`);
- MuJoCo warns of nothing while it runs (no "simulation is unstable", no full contact buffer);
- every arm the run drives (for a two-arm task both; a one-arm task on a two-arm robot uses the robot's
  first arm, the right one of the WidowX pair) commands nothing beyond its velocity, acceleration, jerk and
  range limits (:func:`~besman.sim.executor.limit_violations`), but for the range passes listed in
  :data:`RANGE_PASSED`.

The seeds: those each pair was first accepted on (:data:`FIRST_SEED`: the UR5e's and the WidowX's were
chosen as seeds no other test or tuning used), 0-9 for the others.
"""

from __future__ import annotations

import pytest
from helpers import run_within_limits

import besman.robots as robots
from besman import examples
from besman.sim.outcomes import PLACE_TOLERANCE
from besman.tasks import TASKS
from besman.tasks.sort import places as sort_places
from besman.tasks.throwing import THROW_TOLERANCE

SEEDS = 10
ARMS_APART = 0.03  # m: the margin of the handover tree's KeepApart guards (examples/trees/handover.yaml)

# Every robot: the catalogue's by name, then the examples' robot folders by path.
ROBOTS = [
    *robots.available(),
    *sorted(str(path.parent) for path in examples.path("robots").glob("*/description.json")),
]
PAIRS = [
    (name, robot)
    for name, entry in TASKS.items()
    if entry.tree is not None
    for robot in ROBOTS
    if entry.fits(robots.describe(robot))
]

# (task, robot name): the first of the pair's ten seeds, where it is not 0.
FIRST_SEED = {
    ("pick-place", "ur5e"): 1000,
    ("sort", "ur5e"): 1000,
    ("pick-place", "widowx_ai"): 3801,
    ("sort", "widowx_ai"): 3811,
    ("handover", "widowx_ai_pair"): 3841,
    ("pick-place", "widowx_ai_pair"): 3851,
    ("sort", "widowx_ai_pair"): 3861,
}

# (task, robot name): how far (rad or m) beyond RANGE_SLACK a run may pass a joint's range where a planned
# pose lies on it; open, both: the OpenArm's left shoulder, 1.3963 rad, passed by 4.5 mrad in the handover at
# seed 2; AILA's right shoulder J_Shoulder2_r passed by 0.6 mrad in the stack at seed 4 (found when this
# test first checked AILA's demos against its limits).
RANGE_PASSED = {("handover", "openarm"): 0.005, ("stack", "aila"): 0.001}


def _id(pair: tuple[str, str]) -> str:
    name, robot = pair
    return f"{name}-{robots.describe(robot).name}"


def _beyond_limits(violations: list[str], passed: float) -> list[str]:
    """Those of ``violations`` that count: a range passed by no more than ``passed`` does not."""
    return [
        v for v in violations if not (v.startswith("range limit") and float(v.rsplit(" ", 1)[1]) < passed)
    ]


@pytest.mark.slow
@pytest.mark.parametrize(("name", "robot"), PAIRS, ids=[_id(pair) for pair in PAIRS])
def test_the_task_succeeds_ten_of_ten_within_the_robots_limits(name, robot, mujoco_warnings):
    entry, description = TASKS[name], robots.describe(robot)
    key = (name, description.name)
    first = FIRST_SEED.get(key, 0)
    passed = RANGE_PASSED.get(key, 0.0)
    for seed in range(first, first + SEEDS):
        summary, violations = run_within_limits(name, seed, robot)
        assert mujoco_warnings == [], seed
        assert summary.success, (seed, summary.status, summary.message)
        measured = summary.measurements
        assert set(measured) == set(entry.measurements), seed  # as the task (and the docs) list them
        if "placement_error_m" in measured:
            assert measured["placement_error_m"] <= PLACE_TOLERANCE, (seed, measured)
        if "placement_errors_m" in measured:
            assert max(measured["placement_errors_m"].values()) <= PLACE_TOLERANCE, (seed, measured)
        if "slipped" in measured:  # a box taken out of the hand on its way, every time
            assert measured["slipped"] in sort_places(robot), (seed, measured)
        if "miss_m" in measured:
            assert measured["miss_m"] <= THROW_TOLERANCE, (seed, measured)
        if "ticks_arms_touching" in measured:  # never a contact between the arms, at any tick
            assert measured["ticks_arms_touching"] == 0, (seed, measured)
            assert measured["arms_closest_m"] >= ARMS_APART, (seed, measured)
        assert next(iter(violations)) == next(iter(description.arms)), seed  # the robot's first arm leads
        beyond = {arm: _beyond_limits(found, passed) for arm, found in violations.items()}
        assert not any(beyond.values()), (seed, beyond)
