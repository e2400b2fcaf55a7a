"""Legs of a pick or a placement: three top-down hand poses of one orientation solved into joint
configurations one after the other, and the two straight moves between them, at the best hand yaw
(:func:`plan_leg`). :mod:`besman.sim.manipulation` plans picks and placements around legs.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass

import numpy as np

from besman.sim.arm import Arm
from besman.sim.misses import Misses
from besman.sim.primitives import straight_line, top_down
from besman.sim.references import ReferenceSettings, at_rest, joint_reference
from besman.skills import MovementPrimitive, Trajectory


def hand_yaw(arm: Arm, configuration: np.ndarray) -> float:
    """The direction (rad) in which the fingers of a top-down hand close, at ``configuration``."""
    closing = arm.site_pose(configuration).rotation[:, 1]  # see top_down
    return float(np.arctan2(closing[1], closing[0]))


@dataclass(frozen=True)
class Leg:
    """A planned stretch of an episode: three hand poses of one orientation, the joint configurations that
    reach them, and the references of the two straight moves between them."""

    configurations: tuple[np.ndarray, np.ndarray, np.ndarray]
    primitives: tuple[MovementPrimitive, MovementPrimitive]
    references: tuple[Trajectory, Trajectory]
    clearance: float  # smallest distance to a joint limit along the references, as a fraction of the range


# How far (m) a guarded move's hand may go on after it touches something (it brakes within the arm's
# limits): a few mm press a wrongly perceived object; a hand that ran on 3 cm tipped boxes over.
STOP_DISTANCE = 0.01


# How far (m) the hand may stray from the straight line in each vertical move: near the box the fingers
# have 1.5 cm on either side; lifting and retreating only need to stay clear of the furniture.
MAX_DEVIATION = {"descend": 0.005, "place": 0.005, "lift": 0.02, "retreat": 0.02}


def plan_leg(
    arm: Arm,
    start: np.ndarray,
    positions: list[np.ndarray],
    names: tuple[str, str],
    duration: float,
    allowed: tuple[str, ...],
    settings: ReferenceSettings,
    yaws: np.ndarray,
    guarded: frozenset[str] = frozenset(),
    shift=None,
    accept: Callable[[Leg], bool] | None = None,
    misses: Misses | None = None,
) -> Leg | None:
    """The best hand yaw among ``yaws`` for three top-down poses reached one after the other from the
    configuration ``start`` (moved by ``shift(yaw)``, an (x, y) offset, where the poses depend on the
    yaw): each reachable (solved from the previous one), collision-free except with
    ``allowed`` bodies, and the joint-space moves between them (``names``) staying within
    :data:`MAX_DEVIATION` of a straight line; those ``guarded`` planned slow enough to stop within
    :data:`STOP_DISTANCE`. Among the yaws that work, the one whose moves keep farthest
    from the joint limits (the first of ``yaws`` on a tie). Where no yaw reaches the poses, the yaws turned
    by 180 deg are tried (the same grasps, by the hand's symmetry): a left arm reaches those of a right
    arm mirrored. Where no yaw works from ``start``, the poses are solved from the arm's home (inverse
    kinematics started elsewhere finds other branches; the caller's move to the leg starts at ``start`` all
    the same). ``accept(leg)``, if given, must hold of the chosen leg (what the caller plans around it).
    ``misses`` collects the checks that candidates failed.

    Building a yaw's moves is the expensive part, so it is a branch and bound: both moves start at a pose's
    configuration, so the closer of the first two configurations to a limit bounds the yaw's clearance from
    above; yaws are built in order of that bound, and one that cannot beat the best so far is not built.
    The choice is the same as building every yaw."""
    for first in (start, arm.home):
        best = _best_leg(
            arm, first, positions, names, duration, allowed, settings, yaws, guarded, shift, accept, misses
        )
        if best is not None:
            return best
    return None


def _best_leg(
    arm, first, positions, names, duration, allowed, settings, yaws, guarded, shift, accept, misses
) -> Leg | None:
    """:func:`plan_leg`'s choice with the poses solved from the configuration ``first``."""
    candidates = []
    for turned in (yaws, yaws + np.pi):
        for index, yaw in enumerate(turned):
            orientation = top_down(yaw)
            poses = positions if shift is None else [p + np.r_[shift(yaw), 0.0] for p in positions]
            turn = f"hand yaw {np.degrees(yaw):.0f} deg"
            labels = (f"where {names[0]} starts", f"where {names[0]} ends", f"where {names[1]} ends")
            labels = tuple(f"{label}, {turn}," for label in labels)
            configurations = pose_configurations(arm, first, poses, orientation, allowed, misses, labels)
            if configurations is not None:
                bound = min(arm.limit_margin(configurations[0]), arm.limit_margin(configurations[1]))
                candidates.append((bound, index, orientation, configurations, poses))
        if candidates:
            break
    best, best_index = None, len(yaws)
    for bound, index, orientation, configurations, poses in sorted(candidates, key=lambda c: (-c[0], c[1])):
        if best is not None and (bound, -index) <= (best.clearance, -best_index):
            break  # neither this yaw nor any after it can beat the best
        leg = _build_leg(
            arm, configurations, poses, orientation, names, duration, allowed, settings, guarded, misses
        )
        if leg is not None and accept is not None and not accept(leg):
            continue
        if leg is not None and (best is None or (leg.clearance, -index) > (best.clearance, -best_index)):
            best, best_index = leg, index
    return best


def pose_configurations(
    arm: Arm,
    start: np.ndarray,
    positions: list[np.ndarray],
    orientation: np.ndarray,
    allowed: tuple[str, ...],
    misses: Misses | None = None,
    labels: tuple[str, ...] = (),
) -> list[np.ndarray] | None:
    """Collision-free configurations for the poses, each solved from the previous one; None if one fails
    (recorded in ``misses`` under the pose's label, the second pose the lowest).

    Where a pose's solution collides (an elbow in the robot's chest when the object is near its middle),
    the arm may reach it on another branch: that pose is solved from :data:`BRANCH_TRIES` configurations
    drawn over the ranges (a fixed seed: plans repeat), and the other poses from the first collision-free
    solution outwards."""
    configurations, previous = [], start
    for index, position in enumerate(positions):
        result = arm.solve_ik(position, orientation, initial=previous, restarts=4 if index == 0 else 0)
        if not result.success:
            if misses is not None:
                misses.unreachable(labels[index], position, result, index)
            return None
        hits = arm.contacts(result.qpos, allowed)
        if hits:
            # The hand's pose is the pose's on every branch: a hand in the furniture stays there.
            fixed = any(hit.hand and hit.furniture for hit in hits)
            configurations = None if fixed else _from_branch(arm, positions, index, orientation, allowed)
            if configurations is None and misses is not None:
                misses.collision(labels[index], position, hits[0], index, lowest=index == 1)
            return configurations
        configurations.append(result.qpos)
        previous = result.qpos
    return configurations


BRANCH_TRIES = 8


def _from_branch(arm: Arm, positions, index: int, orientation, allowed) -> list[np.ndarray] | None:
    """:func:`pose_configurations` anchored at pose ``index`` on a collision-free branch, if one is found."""
    rng = np.random.default_rng(index)
    for _ in range(BRANCH_TRIES):
        result = arm.solve_ik(positions[index], orientation, initial=rng.uniform(arm.lower, arm.upper))
        if not result.success or arm.collisions(result.qpos, allowed):
            continue
        below = _chain(arm, result.qpos, positions[index - 1 :: -1] if index else [], orientation, allowed)
        above = _chain(arm, result.qpos, positions[index + 1 :], orientation, allowed)
        if below is None or above is None:
            return None
        return [*below[::-1], result.qpos, *above]
    return None


def _chain(arm: Arm, previous: np.ndarray, positions, orientation, allowed) -> list[np.ndarray] | None:
    """Collision-free configurations for the poses in order, each solved from the one before (the first
    from ``previous``); None if one fails."""
    configurations = []
    for position in positions:
        solved = arm.solve_ik(position, orientation, initial=previous)
        if not solved.success or arm.collisions(solved.qpos, allowed):
            return None
        configurations.append(solved.qpos)
        previous = solved.qpos
    return configurations


def _build_leg(
    arm: Arm,
    configurations: list[np.ndarray],
    positions: list[np.ndarray],
    orientation: np.ndarray,
    names: tuple[str, str],
    duration: float,
    allowed: tuple[str, ...],
    settings: ReferenceSettings,
    guarded: frozenset[str],
    misses: Misses | None = None,
) -> Leg | None:
    """The two straight moves between the poses, if they stay straight and collision-free (what fails is
    recorded in ``misses``)."""
    primitives = [
        straight_line(
            name,
            a,
            b,
            orientation,
            arm,
            duration,
            stop_within=STOP_DISTANCE if name in guarded else None,
        )
        for name, a, b in zip(names, configurations[:-1], positions[1:], strict=True)
    ]
    if any(primitive is None for primitive in primitives):
        return None
    references = tuple(
        joint_reference(arm, primitive, at_rest(a), settings)
        for primitive, a in zip(primitives, configurations[:-1], strict=True)
    )
    turn = f"at hand yaw {np.degrees(hand_yaw(arm, configurations[0])):.0f} deg"
    for name, reference, a, b in zip(names, references, positions[:-1], positions[1:], strict=True):
        strays = deviation(arm, reference, a, b)
        if strays >= MAX_DEVIATION[name]:
            if misses is not None:
                misses.crooked(f"{name} {turn}", strays, MAX_DEVIATION[name])
            return None
    joints = np.concatenate([reference.positions for reference in references])
    for q in joints[:: max(1, len(joints) // 20)]:
        hits = arm.collisions(q, allowed)
        if hits:
            if misses is not None:
                misses.moving_collision(f"{' and '.join(names)} {turn}", hits[0])
            return None
    ends = [configurations[0], *(reference.positions[-1] for reference in references)]
    return Leg(tuple(ends), tuple(primitives), references, arm.limit_margin(joints))


def site_path(arm: Arm, reference: Trajectory, samples: int = 20) -> np.ndarray:
    """Positions of the arm's site along a joint reference (about ``samples`` of them)."""
    return arm.site_path(reference.positions[:: max(1, len(reference.times) // samples)])


def deviation(arm: Arm, reference: Trajectory, start: np.ndarray, end: np.ndarray) -> float:
    """Largest distance of the site's path along a joint reference from the straight segment start-end."""
    path = site_path(arm, reference)
    direction = (end - start) / np.linalg.norm(end - start)
    offsets = path - start
    return float(np.linalg.norm(offsets - np.outer(offsets @ direction, direction), axis=1).max())
