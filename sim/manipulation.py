"""Planning top-down pick and place motions for an arm, as movement primitives.

A pick is three hand poses above, at and over the object (reach, grasp, lift); a placement is three over,
at and above the target (carry, place, retreat). :func:`plan_pick` and :func:`plan_place` choose the hand
yaw (across a pair of the box's faces) for which every pose is reachable and collision-free and the
vertical moves stay close to a straight line, keeping farthest from the joint limits, and return joint-space
movement primitives: reach and carry are point-to-point DMPs, the vertical moves DMPs imitating
inverse-kinematics solutions along the line (:mod:`besman.sim.primitives`). Behaviour-tree leaves and the
scripted pick-and-place task execute them the same way. A plan that cannot be made raises
:class:`~besman.sim.misses.PlanningError` naming the check that the nearest candidate failed, with
its numbers, and what to change.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass

import numpy as np

from besman.core.errors import InputError
from besman.core.moved import old_names
from besman.core.validation import finite_array
from besman.sim.arm import Arm
from besman.sim.legs import Leg, hand_yaw, plan_leg, pose_configurations, site_path
from besman.sim.misses import Misses, PlanningError
from besman.sim.objects import FINGER_CLEARANCE, GraspableObject, yaw_of, yaw_symmetry
from besman.sim.plans import GUARDED_MOVES, PickPlacePlan, Target
from besman.sim.primitives import point_to_point, shaped, straight_line, top_down
from besman.sim.references import DEFAULT_SETTINGS, ReferenceSettings, at_rest, joint_reference
from besman.sim.world import World
from besman.skills import MovementPrimitive

# Hand yaws where the orientation is free (an object set down at any yaw): across a pair of faces of an
# axis-aligned box (0 or 90 deg, up to 15 deg off).
GRASP_YAWS = np.radians([0.0, 15.0, -15.0, -90.0, -75.0, 75.0])
# Hand yaws relative to the object's: the fingers close squarely across a pair of a box's faces, from
# either side (a grasp at an angle holds the box by its edges, and it turns in the hand as it is carried);
# a cylinder's continuum every 30 deg. The hand's own symmetry makes yaws 180 deg apart the same grasp,
# reached by other joint angles.
BOX_GRASPS = np.radians([0.0, 90.0, 180.0, 270.0])
CYLINDER_GRASPS = np.radians(np.arange(0.0, 360.0, 30.0))
LIFT = 0.06  # m a held object is lifted at least (another hand lets go of it below)
LIFTS = 4  # heights tried for a lift, from carrying height down to LIFT
CARRY_RAISE = 0.08  # m higher a carry ends above its target where the direct one dips over the shelf
# m a reach keeps from the furniture: a fast joint-space move's hand strays up to 2.3 cm from its commanded
# path (AILA, measured), and a reach 1.5 cm from the shelf's edge caught a finger on it.
REACH_MARGIN = 0.03
# rad an object may stand turned in the hand from the grasp planned (it settles as the fingers close): a
# grasp is chosen for a placement reachable at these turns too, not only at the planned one.
HELD_SLACK = np.radians(2.0)
RESTING = 0.01  # m from its height standing on the table that an object's centre counts as standing there


def grasp_yaws(item: GraspableObject, arm: Arm, yaw: float = 0.0) -> np.ndarray:
    """The hand yaws (rad, world) at which the arm's open fingers fit around ``item`` standing at ``yaw``:
    its width along the closing direction plus :data:`~besman.sim.objects.FINGER_CLEARANCE` on both sides
    within the aperture (twice the gripper's grasping opening). A 6 cm cube allows every yaw of
    :data:`BOX_GRASPS`; a bar only those across it; a cylinder those of :data:`CYLINDER_GRASPS`."""
    relative, width = _grasp_widths(item)
    return yaw + relative[width + 2 * FINGER_CLEARANCE <= 2 * arm.gripper.open]


def _grasp_widths(item: GraspableObject) -> tuple[np.ndarray, np.ndarray]:
    """The grasp yaws relative to ``item`` and its width (m) across the fingers at each."""
    if item.shape == "cylinder":
        return CYLINDER_GRASPS, np.full(len(CYLINDER_GRASPS), item.narrowest)
    half_x, half_y = item.footprint
    return BOX_GRASPS, 2 * (half_x * np.abs(np.cos(BOX_GRASPS)) + half_y * np.abs(np.sin(BOX_GRASPS)))


def place_yaws(item: GraspableObject, place_yaw: float, held: float) -> np.ndarray:
    """The hand yaws (rad) at which ``item``, held turned by ``held`` from the hand's yaw, stands at
    ``place_yaw`` once set down: every turn of its symmetry (a cylinder: any hand yaw of
    :data:`CYLINDER_GRASPS`)."""
    period = yaw_symmetry(item)
    if period == 0.0:
        return CYLINDER_GRASPS
    return place_yaw - held + period * np.arange(round(2 * np.pi / period))


def _can_set_down(arm: Arm, item: GraspableObject, target: Target, held: float, heights) -> bool:
    """Whether the hand reaches, collision-free, the poses over ``target`` at ``heights`` (each solved from
    the one before) at one of the yaws that set ``item`` down at the target's yaw, held turned by
    ``held`` (give or take :data:`HELD_SLACK`)."""
    positions = [np.r_[target.xy, z] for z in heights]
    return any(
        all(
            pose_configurations(arm, arm.home, positions, top_down(yaw + turn), (item.name,)) is not None
            for turn in (0.0, -HELD_SLACK, HELD_SLACK)
        )
        for yaw in place_yaws(item, target.yaw, held)
    )


@dataclass(frozen=True)
class PickMotions:
    """Reach (from the configuration it was planned from), descend and lift, and the configuration
    after it."""

    reach: MovementPrimitive
    descend: MovementPrimitive
    lift: MovementPrimitive
    lifted: np.ndarray


@dataclass(frozen=True)
class PlaceMotions:
    """Carry (from the configuration it was planned from), place and retreat."""

    carry: MovementPrimitive
    place: MovementPrimitive
    retreat: MovementPrimitive


def heights(world: World, item: GraspableObject, plan: PickPlacePlan) -> tuple[float, float, float]:
    """Heights of the grasp point when grasping on the world's table, carrying and placing on its shelf."""
    table, shelf = world.surface("table").height, world.surface("shelf").height
    grasp = table + item.half_height + plan.grasp_height
    carry = shelf + plan.clearance + item.half_height + plan.grasp_height
    place = shelf + plan.release_height + item.half_height + plan.grasp_height
    return grasp, carry, place


def _place_heights(world: World, item: GraspableObject, plan: PickPlacePlan, target) -> tuple[float, float]:
    """Heights of the grasp point carrying ``item`` over ``target`` and setting it down there: on the
    world's shelf, or onto the target's top (carried clear of it)."""
    _, carry_z, place_z = heights(world, item, plan)
    if target.top is not None:
        place_z = target.top + plan.release_height + item.half_height + plan.grasp_height
        carry_z = max(carry_z, place_z - plan.release_height + plan.clearance)
    return carry_z, place_z


def plan_pick(
    arm: Arm,
    start: np.ndarray,
    item: GraspableObject,
    object_xy,
    plan: PickPlacePlan,
    settings: ReferenceSettings = DEFAULT_SETTINGS,
    reach: Learned | None = None,
    yaw: float = 0.0,
    then=None,
) -> PickMotions:
    """Motions that grasp ``item`` at ``object_xy`` (standing on the table) or ``(x, y, z)`` (its centre
    at height z: at its resting height it stands on the table, else e.g. another hand holds it), turned by
    ``yaw`` (rad), from the configuration ``start`` and lift it to carrying height (an object in the air at
    least :data:`LIFT` up). Of the grasps that fit (:func:`grasp_yaws`) the one that keeps farthest from the
    joint limits, its reach clear of the furniture. The reach is a point-to-point
    move, or a joint-space primitive learned from people moved to this reach's end points
    (:func:`~besman.sim.primitives.shaped`): ``reach``, or ``reach(start, end)`` the primitive for them.

    ``then``: the target (:meth:`Target.read`) of the placement the grasp is for. Where the target has a
    yaw, the grasp is one from which the object can be set down turned to it (a box held across one pair
    of faces stands at the place's yaw for two hand yaws only, which the wrist may not reach there), if
    there is such a grasp; and one from where it is lifted, the object can be carried (point to point) to
    the target and set down there."""
    where = np.asarray(object_xy, dtype=float)
    object_xy = where[:2]
    grasp_z, carry_z, _ = heights(arm.world, item, plan)
    # On the table (given as x, y or at its resting height, as perceived), or held in the air.
    standing = len(where) == 2 or abs(where[2] + plan.grasp_height - grasp_z) < RESTING
    if not standing:
        grasp_z = where[2] + plan.grasp_height
        carry_z = max(carry_z, grasp_z + LIFT)
    target = None if then is None else then if isinstance(then, Target) else Target.read(then)
    misses, failed = Misses(arm), f"no top-down grasp of {item.name} at {np.round(where, 3).tolist()}"
    yaws = _grasps_for(arm, item, yaw, target, plan)
    if len(yaws) == 0:
        narrowest = float(_grasp_widths(item)[1].min())
        misses.fits(narrowest, narrowest + 2 * FINGER_CLEARANCE)
        raise misses.error(failed)
    # Lifted to carrying height, or where the wrist cannot reach that high at the yaw the object needs, as
    # high as it can, at least LIFT up (the carry then rises over the shelf: the lower it starts, the more
    # likely it dips).
    lifts = np.linspace(carry_z, grasp_z + LIFT, LIFTS) if carry_z > grasp_z + LIFT else [carry_z]
    reaches, missing = {}, []  # per leg its reach; legs that passed some checks, with those they missed

    def placeable(lifted: np.ndarray) -> bool:
        try:  # the object turned in the hand as planned: as it stands now against the hand lifted
            plan_place(arm, lifted, item, target, plan, settings)
        except PlanningError:
            return False
        return True

    def passes(leg: Leg) -> bool:
        """Whether the leg passes every check: on the way to an object on the table its reach touches
        nothing (the object least of all: the joint-space reach comes to it from the side; one held in the
        air by another hand is the tree's to keep apart) and keeps :data:`REACH_MARGIN` from the
        furniture, and from where it lifts the object, it can be carried to ``then`` and set down there.
        A leg that misses only the margin or the placement is kept in ``missing``."""
        move = _big_move("reach", reach, start, leg.configurations[0], arm)
        path = joint_reference(arm, move, at_rest(start), settings).positions
        path = path[:: max(1, len(path) // 30)]
        near = standing and any(arm.collisions(q, margin=REACH_MARGIN) for q in path)
        hits = next((hits for q in path if (hits := arm.collisions(q))), None) if near else None
        if hits:
            misses.moving_collision("the reach to above the object", hits[0])
            return False
        reaches[id(leg)] = move
        missed = (target is not None and not placeable(leg.configurations[-1]), near)
        if any(missed):
            missing.append((missed, leg))
        return not any(missed)

    # Lifted as high as it passes and stays in every joint's range (a lift planned past a limit fails when it
    # runs: seed 1102's by 0.075 rad, so it is kept only in case no lower one is); where no leg passes every
    # check, the first that misses the least (the placement before the margin).
    leg = None
    for lift in lifts:
        candidate = _vertical_leg(
            arm,
            start,
            object_xy,
            lambda approach, lift=lift: (grasp_z + approach, grasp_z, lift),
            ("descend", "lift"),
            item,
            plan,
            settings=settings,
            yaws=yaws,
            accept=passes,
            misses=misses,
        )
        if candidate is not None and candidate.clearance >= -OVERSHOOT:
            leg = candidate
            break
        leg = leg or candidate
    if leg is None and missing:
        leg = min(missing, key=lambda found: found[0])[1]
    if leg is None:
        raise misses.error(failed)
    return PickMotions(reaches[id(leg)], *leg.primitives, leg.configurations[-1])


# m the open fingers reach below the grasp point, and the gap they keep above an object's top before they
# move sideways: the least height above the grasp point of a pose that comes from or goes to the side.
FINGER_DEPTH = 0.04
TOP_GAP = 0.01


def _clearances(item: GraspableObject, plan: PickPlacePlan) -> tuple[float, ...]:
    """How high above the grasp point the hand comes from or goes to the side of an object: the plan's
    approach height, or where the wrist cannot reach that high at the yaw the object needs, just above
    the object's top."""
    least = item.half_height - plan.grasp_height + FINGER_DEPTH + TOP_GAP
    return (plan.approach_height,) if least >= plan.approach_height else (plan.approach_height, least)


# How far (a fraction of its range) a straight move's imitation may pass a joint's limit: its knots are
# inverse-kinematics solutions at the limit, and the execution holds the joint there (a hair's deviation
# from the line); farther, it would run into the limit at speed.
OVERSHOOT = 0.0


def _vertical_leg(arm: Arm, start, xy, heights, names, item: GraspableObject, plan: PickPlacePlan, **options):
    """The leg down to ``xy`` and up again through the three ``heights(clearance)``, for each of the
    object's clearances (:func:`_clearances`) in turn: the first within every joint's range, else the first
    planned (:func:`_first_within_range`); ``options`` go to :func:`plan_leg`."""
    return _first_within_range(
        plan_leg(
            arm,
            start,
            [np.r_[xy, z] for z in heights(clearance)],
            names,
            plan.descend_time,
            allowed=(item.name,),
            guarded=GUARDED_MOVES,
            **options,
        )
        for clearance in _clearances(item, plan)
    )


def _first_within_range(legs) -> Leg | None:
    """The first of the planned ``legs`` (planned one by one, None where one cannot be) whose moves stay in
    every joint's range (up to :data:`OVERSHOOT`), else the first planned."""
    first = None
    for leg in legs:
        if leg is not None and leg.clearance >= -OVERSHOOT:
            return leg
        first = first or leg
    return first


def _grasps_for(
    arm: Arm, item: GraspableObject, yaw: float, target: Target | None, plan: PickPlacePlan
) -> np.ndarray:
    """The grasp yaws of ``item`` standing at ``yaw`` from which it can be set down at ``target`` (all
    that fit if none can, or without a target's yaw)."""
    yaws = grasp_yaws(item, arm, yaw)
    if target is None or target.yaw is None or yaw_symmetry(item) == 0.0:
        return yaws
    carry_z, place_z = _place_heights(arm.world, item, plan, target)
    # Above the target, at it, and the lowest retreat from it (the wrist may reach the carry's height at
    # a yaw and not the retreat's, a few cm higher).
    place = (carry_z, place_z, place_z + min(_clearances(item, plan)))
    fitting = [grasp for grasp in yaws if _can_set_down(arm, item, target, yaw - grasp, place)]
    return np.array(fitting) if fitting else yaws


# A learned big move (reach, carry): a primitive, or a function of the move's start and end configurations
# that gives one (a skill template's instance for them).
Learned = MovementPrimitive | Callable[[np.ndarray, np.ndarray], MovementPrimitive]


def _big_move(
    name: str, learned: Learned | None, start, end, arm: Arm, *duration: float
) -> MovementPrimitive:
    """The move ``name`` from ``start`` to ``end``: point to point (lasting at least ``duration``), or the
    ``learned`` primitive moved there."""
    if learned is None:
        return point_to_point(name, start, end, arm, *duration)
    shape = learned(start, end) if callable(learned) else learned
    return shaped(shape, name, start, end, arm)


def plan_place(
    arm: Arm,
    start: np.ndarray,
    item: GraspableObject,
    target,
    plan: PickPlacePlan,
    settings: ReferenceSettings = DEFAULT_SETTINGS,
    carry: Learned | None = None,
    held=None,
) -> PlaceMotions:
    """Motions that carry ``item`` from the configuration ``start`` (holding it at carrying height) to the
    ``target`` (:meth:`Target.read`: on the shelf or onto a top, turned to a yaw modulo the object's
    symmetry or any), set it down and retreat. The carry is a point-to-point move, or a joint-space
    primitive learned from people moved to its end points (``carry``, or ``carry(start, end)`` the primitive
    for them, as :func:`plan_pick` takes its reach).

    ``held`` (x, y) is where the object's centre is from the hand's grasp point now, for an object held
    off-centre (a bar taken at one end): the object, not the hand, goes to the target, and since the
    object turns with the hand, the offset is turned with the hand's yaw."""
    target = target if isinstance(target, Target) else Target.read(target)
    place_xy = target.xy
    carry_z, place_z = _place_heights(arm.world, item, plan, target)
    if target.yaw is None:
        yaws = GRASP_YAWS
    else:
        turned = yaw_of(arm.world.object_pose(item.name).rotation) - hand_yaw(arm, start)
        yaws = place_yaws(item, target.yaw, turned)
    shift = None
    if held is not None:
        held = np.asarray(held, dtype=float)
        now = hand_yaw(arm, start)

        def shift(hand: float) -> np.ndarray:
            turn = hand - now
            rotation = np.array([[np.cos(turn), -np.sin(turn)], [np.sin(turn), np.cos(turn)]])
            return -(rotation @ held)

    carries, swept = {}, []  # per leg its carry; how low the carries that swept the shelf went
    misses = Misses(arm)

    shelf = arm.world.surface("shelf")
    reach = float(np.hypot(*item.footprint))  # how far the object reaches from its centre in the plane

    def carried_clear(leg: Leg) -> bool:
        """The carry to the leg's first configuration, if the object stays clear above the shelf wherever
        it is over it (the joint-space carry cannot run into a joint limit, but it can dip)."""
        move = _big_move("carry", carry, start, leg.configurations[0], arm, plan.carry_time)
        reference = joint_reference(arm, move, at_rest(start), settings)
        path = site_path(arm, reference, 40)
        over = [shelf.contains(x, y, -reach) for x, y in path[:, :2]]
        lowest = float(path[over, 2].min()) if any(over) else np.inf
        if lowest - item.half_height - plan.grasp_height < shelf.height + 0.01:
            swept.append(lowest)
            return False
        carries[id(leg)] = move
        return True

    # Carried to above the target, or where that carry dips over the shelf's edge, to higher above it (a
    # joint-space carry from a low lift climbs more steeply to a higher end).
    for above in (carry_z, carry_z + CARRY_RAISE):
        leg = _vertical_leg(
            arm,
            start,
            place_xy,
            lambda retreat, above=above: (above, place_z, place_z + retreat),
            ("place", "retreat"),
            item,
            plan,
            settings=settings,
            yaws=yaws,
            shift=shift,
            accept=carried_clear,
            misses=misses,
        )
        if leg is not None or not swept:
            break
    if leg is None and swept:
        raise PlanningError(
            f"the carry would sweep the object over the shelf with the hand down at z = {min(swept):.3f} m "
            f"(the shelf's top is at {shelf.height:.3f} m)"
        )
    if leg is None:
        raise misses.error(f"no top-down placement of {item.name} at {np.round(target.xy, 3).tolist()}")
    return PlaceMotions(carries[id(leg)], *leg.primitives)


def plan_move(
    arm: Arm,
    start: np.ndarray,
    *,
    position=None,
    rise: float | None = None,
    home: bool = False,
    yaw: float | None = None,
    allowed: tuple[str, ...] = (),
    duration: float = 1.0,
) -> MovementPrimitive:
    """A move of the hand from the configuration ``start``, exactly one of: to ``position`` (x, y, z) with
    the hand's orientation kept, or pointing down turned by ``yaw`` (point to point in joint space), straight
    up by ``rise`` m, or back to the robot's home configuration. The end must be collision-free (except with
    ``allowed`` bodies, e.g. an object in the hand); a rise must stay straight."""
    if sum((position is not None, rise is not None, home)) != 1:
        raise InputError("a move goes to a position, rises, or goes home: exactly one of them")
    if home:
        return point_to_point("home", start, arm.world.home(arm.qpos_indices), arm, duration)
    hand = arm.site_pose(start)
    if rise is not None:
        goal_position = hand.position + [0.0, 0.0, rise]
        primitive = straight_line("rise", start, goal_position, hand.quaternion, arm, duration)
        if primitive is None:
            raise PlanningError(f"no straight rise of {rise:g} m from here")
        return primitive
    goal_position = finite_array("position", position)
    orientation = hand.quaternion if yaw is None else top_down(yaw)
    result = arm.solve_ik(goal_position, orientation, initial=start, restarts=4)
    if not result.success:
        raise PlanningError(f"the hand cannot reach {np.round(goal_position, 3).tolist()} as it is turned")
    hit = arm.collisions(result.qpos, allowed)
    if hit:
        raise PlanningError(f"the hand at {np.round(goal_position, 3).tolist()} would collide: {hit[0]}")
    return point_to_point("move", start, result.qpos, arm, duration)


__getattr__ = old_names(__name__)  # the old names, for one release (besman.core.moved)
