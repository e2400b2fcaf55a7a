"""Planning top-down pick and place motions for an executor, as movement primitives.

A pick is three hand poses above, at and over the object (approach, grasp, lift); a placement is three over,
at and above the target (carry, place, retreat). :func:`plan_pick` and :func:`plan_place` choose the hand
yaw (across a pair of the box's faces) for which every pose is reachable and collision-free and the
vertical moves stay close to a straight line, keeping farthest from the joint limits, and return joint-space
movement primitives: approach and transport are point-to-point DMPs, the vertical moves DMPs imitating
inverse-kinematics solutions along the line (:mod:`besman.sim.primitives`). Behaviour-tree leaves and the
scripted pick-and-place task execute them the same way. A plan that cannot be made raises
:class:`PlanningError` with the reason.
"""

from __future__ import annotations

from dataclasses import astuple, dataclass, fields

import numpy as np

import besman.robots as robots
from besman.sim.executor import Executor
from besman.sim.primitives import point_to_point, straight_line, top_down
from besman.sim.world import SHELF, TABLE, GraspableObject
from besman.skills import MovementPrimitive, Trajectory
from besman.skills.validation import finite_array


class PlanningError(ValueError):
    """No motion satisfies the plan's conditions; the message says which."""


OPEN = 0.045  # finger opening (m per finger) before grasping and for releasing: a 9 cm aperture
# The fingers close across a pair of the box's faces (yaw 0 or 90 deg, up to 15 deg off); the hand's own
# symmetry makes yaws 180 deg apart the same grasp.
GRASP_YAWS = np.radians([0.0, 15.0, -15.0, -90.0, -75.0, 75.0])


@dataclass(frozen=True)
class PickPlacePlan:
    """The parameters of the scripted plan; theta is these numbers in this order."""

    approach_height: float = 0.10  # m above the grasp point before descending
    clearance: float = 0.06  # m between the box's bottom and the shelf top at the ends of the transport
    grasp_height: float = 0.01  # m above the box's centre where the fingers close (the tips clear the table)
    release_height: float = 0.003  # m above the shelf where the box is let go
    transport_time: float = 2.0  # s
    descend_time: float = 1.0  # s for each descent, lift and retreat

    @classmethod
    def from_theta(cls, theta) -> PickPlacePlan:
        theta = finite_array("theta", theta)
        if theta.shape != (len(fields(cls)),):
            raise ValueError(
                f"theta must have {len(fields(cls))} entries "
                f"({', '.join(f.name for f in fields(cls))}), got shape {theta.shape}"
            )
        plan = cls(*(float(v) for v in theta))
        if not (
            0.03 <= plan.approach_height <= 0.3
            and 0.0 <= plan.clearance <= 0.3
            and plan.transport_time >= 0.3
            and plan.descend_time >= 0.3
            and abs(plan.grasp_height) <= 0.03
            and 0.0 <= plan.release_height <= 0.05
        ):
            raise ValueError(f"theta is outside the plan's valid ranges: {plan}")
        return plan

    def theta(self) -> np.ndarray:
        return np.array(astuple(self))


@dataclass(frozen=True)
class _Leg:
    """A planned stretch of an episode: three hand poses of one orientation, the joint configurations that
    reach them, and the references of the two straight moves between them."""

    configurations: tuple[np.ndarray, np.ndarray, np.ndarray]
    primitives: tuple[MovementPrimitive, MovementPrimitive]
    references: tuple[Trajectory, Trajectory]
    clearance: float  # smallest distance to a joint limit along the references, as a fraction of the range


# How far (m) the hand may stray from the straight line in each vertical move: near the box the fingers
# have 1.5 cm on either side; lifting and retreating only need to stay clear of the furniture.
MAX_DEVIATION = {"descend": 0.005, "place": 0.005, "lift": 0.02, "retreat": 0.02}


def plan_leg(
    executor: Executor,
    start: np.ndarray,
    positions: list[np.ndarray],
    names: tuple[str, str],
    duration: float,
    allowed: tuple[str, ...],
) -> _Leg | None:
    """The best hand yaw for three top-down poses reached one after the other from the configuration
    ``start``: each reachable (solved from the previous one), collision-free except with ``allowed`` bodies,
    and the joint-space moves between them (``names``) staying within :data:`MAX_DEVIATION` of a straight
    line. Among the yaws that work, the one whose moves keep farthest from the joint limits."""
    best: _Leg | None = None
    span = executor.upper - executor.lower
    for yaw in GRASP_YAWS:
        orientation, configurations, previous = top_down(yaw), [], start
        for index, position in enumerate(positions):
            result = executor.solve_ik(
                position, orientation, initial=previous, restarts=4 if index == 0 else 0
            )
            if not result.success or executor.collisions(result.qpos, allowed):
                break
            configurations.append(result.qpos)
            previous = result.qpos
        else:
            primitives = [
                straight_line(name, a, b, orientation, executor, duration)
                for name, a, b in zip(names, configurations[:-1], positions[1:], strict=True)
            ]
            if any(primitive is None for primitive in primitives):
                continue
            references = tuple(
                executor.primitive_reference(primitive, start=a)
                for primitive, a in zip(primitives, configurations[:-1], strict=True)
            )
            configurations[1:] = [reference.positions[-1] for reference in references]
            straight = all(
                deviation(executor, reference, a, b) < MAX_DEVIATION[name]
                for name, reference, a, b in zip(
                    names, references, positions[:-1], positions[1:], strict=True
                )
            )
            joints = np.concatenate([reference.positions for reference in references])
            if straight and not any(
                executor.collisions(q, allowed) for q in joints[:: max(1, len(joints) // 20)]
            ):
                clearance = float((np.minimum(joints - executor.lower, executor.upper - joints) / span).min())
                if best is None or clearance > best.clearance:
                    best = _Leg(tuple(configurations), tuple(primitives), references, clearance)
    return best


def site_path(executor: Executor, reference: Trajectory, samples: int = 20) -> np.ndarray:
    """Positions of the executor's site along a joint reference (about ``samples`` of them)."""
    return np.array(
        [
            robots.forward_kinematics(executor.world.robot, executor.full_qpos(q), executor.site).position
            for q in reference.positions[:: max(1, len(reference.times) // samples)]
        ]
    )


def deviation(executor: Executor, reference: Trajectory, start: np.ndarray, end: np.ndarray) -> float:
    """Largest distance of the site's path along a joint reference from the straight segment start-end."""
    path = site_path(executor, reference)
    direction = (end - start) / np.linalg.norm(end - start)
    offsets = path - start
    return float(np.linalg.norm(offsets - np.outer(offsets @ direction, direction), axis=1).max())


@dataclass(frozen=True)
class PickMotions:
    """Approach (from the executor's state when planned), descend and lift, and the configuration after it."""

    approach: MovementPrimitive
    descend: MovementPrimitive
    lift: MovementPrimitive
    lifted: np.ndarray


@dataclass(frozen=True)
class PlaceMotions:
    """Transport (from the configuration it was planned from), place and retreat."""

    transport: MovementPrimitive
    place: MovementPrimitive
    retreat: MovementPrimitive


def heights(item: GraspableObject, plan: PickPlacePlan) -> tuple[float, float, float]:
    """Heights of the grasp point when grasping on the table, carrying and placing on the shelf."""
    grasp = TABLE.height + item.half_height + plan.grasp_height
    carry = SHELF.height + plan.clearance + item.half_height + plan.grasp_height
    place = SHELF.height + plan.release_height + item.half_height + plan.grasp_height
    return grasp, carry, place


def plan_pick(executor: Executor, item: GraspableObject, object_xy, plan: PickPlacePlan) -> PickMotions:
    """Motions that grasp ``item`` standing on the table at ``object_xy`` and lift it to carrying height."""
    object_xy = np.asarray(object_xy, dtype=float)
    grasp_z, carry_z, _ = heights(item, plan)
    leg = plan_leg(
        executor,
        executor.position,
        [
            np.r_[object_xy, grasp_z + plan.approach_height],
            np.r_[object_xy, grasp_z],
            np.r_[object_xy, carry_z],
        ],
        ("descend", "lift"),
        plan.descend_time,
        allowed=(item.name,),
    )
    if leg is None:
        raise PlanningError("no reachable, collision-free top-down grasp of the object")
    approach = point_to_point("approach", executor.position, leg.configurations[0], executor)
    return PickMotions(approach, *leg.primitives, leg.configurations[-1])


def plan_place(
    executor: Executor, item: GraspableObject, start: np.ndarray, place_xy, plan: PickPlacePlan
) -> PlaceMotions:
    """Motions that carry ``item`` from the configuration ``start`` (holding it at carrying height) to
    ``place_xy`` on the shelf, set it down and retreat."""
    place_xy = np.asarray(place_xy, dtype=float)
    _, carry_z, place_z = heights(item, plan)
    leg = plan_leg(
        executor,
        start,
        [np.r_[place_xy, carry_z], np.r_[place_xy, place_z], np.r_[place_xy, place_z + plan.approach_height]],
        ("place", "retreat"),
        plan.descend_time,
        allowed=(item.name,),
    )
    if leg is None:
        raise PlanningError("no reachable, collision-free top-down placement at the target")
    transport = point_to_point("transport", start, leg.configurations[0], executor, plan.transport_time)
    # The joint-space transport cannot run into a joint limit, but its hand path must stay over the shelf.
    lowest = float(site_path(executor, executor.primitive_reference(transport, start=start), 40)[:, 2].min())
    if lowest - item.half_height - plan.grasp_height < SHELF.height + 0.01:
        raise PlanningError(f"the transport would sweep the box {lowest:.3f} m low over the shelf")
    return PlaceMotions(transport, *leg.primitives)
