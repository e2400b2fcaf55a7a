"""The executor's settings: its control rate and tolerances (:class:`ExecutorConfig`), shared by the executor
(:mod:`besman.sim.executor`) and the motions it runs (:mod:`besman.sim.motions`)."""

from __future__ import annotations

from dataclasses import dataclass

from besman.core.validation import COUNT, checked, integer, non_negative, positive


@checked(
    control_period=positive,
    arrival_tolerance=positive,
    lag_tolerance=positive,
    following_tolerance=positive,
    ik_position_tolerance=positive,
    ik_orientation_tolerance=positive,
    ik_knot_period=positive,
    settle_cycles=integer(0),
    range_tolerance=non_negative,
    lookahead_cycles=COUNT,
    arrival_timeout=positive,
)
@dataclass(frozen=True)
class ExecutorConfig:
    """Control rate and tolerances.

    Attributes:
        control_period: seconds per control cycle (a multiple of the model's timestep).
        arrival_tolerance: joint error (rad or m) at which a motion's final state counts as reached.
        lag_tolerance: largest commanded-vs-reference difference before a reference counts as infeasible.
        following_tolerance: largest actual-vs-commanded joint difference before the robot counts as blocked.
        ik_position_tolerance, ik_orientation_tolerance: accuracy of the IK solutions of Cartesian references.
        ik_acceptance: largest remaining (position, orientation) error of a sample that still counts as
            reached (a joint at its limit can slow the convergence below the tolerance).
        ik_knot_period: seconds between the IK solutions that a Cartesian reference's spline joins.
        settle_cycles: cycles a motion waits at its goal for the robot to settle before it succeeds.
        range_tolerance: how far (rad or m) a reference may pass a joint range (commands are clipped to the
            range) before it is rejected.
        lookahead_cycles: how far ahead on a reference each cycle's Ruckig target lies.
        arrival_timeout: seconds the robot may take to reach a goal after its command got there.
    """

    control_period: float = 0.002
    arrival_tolerance: float = 0.01
    lag_tolerance: float = 0.2
    following_tolerance: float = 0.15
    ik_position_tolerance: float = 1e-7
    ik_orientation_tolerance: float = 1e-6
    ik_acceptance: tuple[float, float] = (1e-5, 1e-4)
    ik_knot_period: float = 0.01
    settle_cycles: int = 25
    range_tolerance: float = 0.02
    lookahead_cycles: int = 10
    arrival_timeout: float = 1.0
