"""Checking a robot for the tabletop tasks: what its description must get right, one check at a time.

``besman robots check ROBOT`` runs these on each arm with a gripper and prints a line per check with its
verdict, what it measured and what to change: what a user bringing an arm would otherwise find one failed
demo at a time. Then each task of the registry checks what it needs of the robot itself
(:meth:`~besman.tasks.base.Task.robot_checks`, with :class:`Finding` and the helpers here): pick and
place checks the first arm's home, its reach of the task's areas and one run
(:mod:`besman.tasks.pick_place.robot_checks`), the handover the bar held by one end
(:meth:`~besman.tasks.handover.Handover.robot_checks`).

- **tool frame**: its y axis runs along the fingers' closing, and it sits between the fingertips: the
  planner grasps 1 cm above an object's centre, so the fingertips must not reach the table under the task's
  object (nor further than :data:`~besman.sim.manipulation.FINGER_DEPTH`, which its approach allows for)
  and the pads must cover at least :data:`PAD_OVERLAP` of the object's height.
- **gripper**: opening and closing moves the pads of both sides; at its ``open`` opening the pads are as far
  apart as the opening table says.
- **holds**: the pads close on the task's object (pick and place's 6 cm box, :func:`checked_object`) from
  both sides, and hold it up against its weight.
- **integrator**: every joint of the arm and its gripper is stable under the model's integrator.
- **limits**: every joint follows a move at its velocity, acceleration and jerk limits within half the
  executor's following tolerance (a position actuator lags its command by its speed times kv / kp).
"""

from __future__ import annotations

import difflib
from collections.abc import Iterator
from dataclasses import replace
from functools import partial

import mujoco
import numpy as np

from besman.robots.assembly import CHOICES
from besman.robots.catalogue import describe
from besman.robots.kinematics import bodies_below
from besman.robots.servos import force_limit, growth_per_step, joint_inertia, servo_gains, steady_lag
from besman.sim.arm import Arm
from besman.sim.executor import Executor, ExecutorConfig
from besman.sim.hand import Hand
from besman.sim.manipulation import FINGER_DEPTH
from besman.sim.motions import MoveTo
from besman.sim.objects import GraspableObject
from besman.sim.plans import DEFAULT_PLAN
from besman.sim.world import World, tabletop_world
from besman.tasks.base import Finding

CLOSING_TILT = 15.0  # deg the line between the pads may lean from the tool frame's y axis
OPENING_SLACK = 0.002  # m the measured opening may differ from the table's at ``open``
# m the hand may reach past its pads along the tool frame's z axis: farther, the axis points into the hand.
INTO_HAND = 0.03
PAD_OVERLAP = 0.01  # m of the object's height that the pads must cover when grasping it
SIDE_TRAVEL = 0.25  # of the opening's range that each side's pads must travel between closed and open
SETTLE = 1.5  # s the fingers get to settle at a command
# s a held object settles in the grip, s it is then watched, m it may slide down meanwhile
HOLD_SETTLE, HOLD_TIME, HOLD_SLIDE = 1.0, 1.0, 0.001
# Of the executor's following tolerance that a joint may lag at its limits, in the check's move or steadily
# at its velocity limit: AILA's shoulders steadily lag 0.116 rad at 1.5 rad/s (0.77 of 0.15) in every demo.
LAG_SHARE = 0.8


def check_robot(robot: str) -> Iterator[Finding]:
    """The checks of the module documentation on ``robot`` (a name or a folder), one finding at a time; then
    each task's own (:meth:`~besman.tasks.base.Task.robot_checks`), every task of the registry once."""
    from besman.tasks import TASKS
    from besman.tasks.pick_place.scene import family

    description = describe(robot)
    yield _sections(description)
    if description.tabletop is None:
        yield Finding(
            next(iter(description.arms), "-"),
            "the tabletop",
            False,
            "the description has no tabletop (the table, the shelf and the area the arm reaches): the checks "
            "need the table",
            f"add tabletop to {description.file} (besman.robots.description lists its fields)",
        )
        return
    item = checked_object(robot)
    heaviest = family(robot).mass[1]
    world = tabletop_world((item,), robot=robot)
    for name, spec in description.arms.items():
        field = f"{description.file}: arms.{name}"
        if spec.gripper is None:
            continue
        checks = [
            partial(_integrator, world, name, description.file),
            partial(_closing, world, name, field),
            partial(_fingertips, world, name, field, item),
            partial(_both_sides, world, name, field),
            partial(_opening, world, name, field),
            partial(_holds, world, name, item),
            partial(_keeps_hold, world, name, replace(item, mass=heaviest)),
            partial(_limits, world, name, description.file),
        ]
        for check in checks:
            world.reset()
            yield check()
    for entry in TASKS.values():  # by name: an alias is not a key, a subclass is a task of its own
        yield from entry.robot_checks(robot, description)


def checked_object(robot: str) -> GraspableObject:
    """The object the checks grasp: pick and place's 6 cm box, as narrow as ``robot``'s first gripper
    needs (the object of its run without a seed), its mass and friction the family's middles."""
    from besman.tasks.pick_place.scene import DEFAULT_OBJECT, family, the_object

    widths = family(robot).width
    size = [min(DEFAULT_OBJECT["size"][0], widths[1])] * 2 + [DEFAULT_OBJECT["size"][2]]
    return the_object(robot, {"shape": np.array([0.0]), "size": np.array(size)}, None)


def _sections(description) -> Finding:
    """Every task section of the description is one a task reads (a misspelt one is otherwise ignored)."""
    from besman.tasks import TASKS

    readers = {name: entry.section for name, entry in TASKS.items() if entry.section}
    unread = [name for name in description.tasks if name not in readers]
    read = "; ".join(f"{name} ({what})" for name, what in readers.items())
    if not unread:
        return Finding(
            "robot", "every task section is read", True, f"tasks: {', '.join(description.tasks) or 'none'}"
        )
    near = difflib.get_close_matches(unread[0], readers, n=1)
    return Finding(
        "robot",
        "every task section is read",
        False,
        f"no task reads tasks.{unread[0]}" + (f" (did you mean {near[0]}?)" if near else ""),
        f"rename or remove it in {description.file}; the sections tasks read: {read}",
    )


def _tool_frame(world: World, name: str) -> tuple[np.ndarray, np.ndarray]:
    """The tool frame's position and rotation now (the world's data, forwarded)."""
    site = world.model.site(world.robot.arm(name).tcp).id
    return world.data.site_xpos[site].copy(), world.data.site_xmat[site].reshape(3, 3).copy()


def _pad_centres(world: World, name: str) -> list[np.ndarray]:
    """Each side's pads' centre, in the tool frame."""
    position, rotation = _tool_frame(world, name)
    return [
        rotation.T @ (world.data.geom_xpos[side].mean(axis=0) - position)
        for side in world.robot.arm(name).gripper.pads
    ]


def _closing(world: World, name: str, field: str) -> Finding:
    one, other = _pad_centres(world, name)
    line = (one - other) / np.linalg.norm(one - other)
    tilt = float(np.degrees(np.arccos(min(1.0, abs(line[1])))))
    return Finding(
        name,
        "tool frame's y axis along the closing",
        tilt <= CLOSING_TILT,
        f"the line between the pads is {tilt:.0f} deg from the tool frame's y axis",
        f"turn the tool frame about its z axis until its y axis runs from finger to finger ({field}.tcp)",
    )


def _fingertips(world: World, name: str, field: str, item) -> Finding:
    """Where the hand's geoms and the pads reach along the tool frame's z axis (out of the hand), against
    where the task's object stands when the planner grasps it (its centre ``grasp_height`` past the tool
    frame, the table under it)."""
    model, data = world.model, world.data
    gripper = world.robot.arm(name).gripper
    position, rotation = _tool_frame(world, name)
    signs = np.array([[x, y, z] for x in (-1, 1) for y in (-1, 1) for z in (-1, 1)])

    def depths(geoms) -> np.ndarray:  # each geom's box corners, along the tool frame's z
        reach = []
        for geom in geoms:
            centre, half = model.geom_aabb[geom, :3], model.geom_aabb[geom, 3:]
            corners = data.geom_xpos[geom] + (centre + signs * half) @ data.geom_xmat[geom].reshape(3, 3).T
            reach.append((corners - position) @ rotation[:, 2])
        return np.concatenate(reach)

    pad_geoms = np.concatenate(gripper.pads)
    tool = model.site_bodyid[model.site(world.robot.arm(name).tcp).id]
    holder = _hand_body(model, tool, pad_geoms)
    if holder == 0:
        return Finding(
            name,
            "tool frame between the fingertips",
            False,
            f"the tool frame's body {model.body(tool).name!r} and the pads hang from no body but the world: "
            "the tool frame is not on the hand",
            f"put the tool frame on the hand: a body the fingers hang from, or one beside them ({field}.tcp)",
        )
    hand = bodies_below(model, [holder])
    colliding = (model.geom_contype != 0) | (model.geom_conaffinity != 0)
    tip = float(depths(np.union1d(np.flatnonzero(hand[model.geom_bodyid] & colliding), pad_geoms)).max())
    pads = depths(pad_geoms)
    centre = DEFAULT_PLAN.grasp_height  # the object's centre, past the tool frame
    bottom, top = centre + item.half_height, centre - item.half_height
    deepest = min(FINGER_DEPTH, bottom)  # the planner's allowance; the table
    overlap = min(pads.max(), bottom) - max(pads.min(), top)
    measured = (
        f"the fingertips reach {tip * 1000:.0f} mm past the tool frame (at most {deepest * 1000:.0f}), the "
        f"pads {pads.min() * 1000:.0f} to {pads.max() * 1000:.0f} mm, the task's object {top * 1000:.0f} to "
        f"{bottom * 1000:.0f} mm"
    )
    if tip > pads.max() + INTO_HAND:
        fix = "the tool frame's z axis points into the hand: turn it to point out along the fingers"
    elif tip > deepest:
        fix = (
            f"move the tool frame {tip - deepest + 0.005:.3f} m further out along its z axis, toward the tips"
        )
    elif overlap < PAD_OVERLAP:
        fix = "move the tool frame along its z axis to the middle of the pads"
    else:
        fix = ""
    return Finding(
        name,
        "tool frame between the fingertips",
        not fix,
        measured,
        f"{fix} ({field}.tcp: a site between the pads, or a body and position)" if fix else "",
    )


def _hand_body(model: mujoco.MjModel, tool: int, pads: np.ndarray) -> int:
    """The lowest body that the tool frame's body ``tool`` and every pad geom hang from: the hand, whose
    geoms reach past the tool frame (a tool frame on a leaf body beside the fingers, with no geom below
    it, measures the fingers beside it); 0, the world, where the tool frame is not on the hand."""
    chain = [int(tool)]
    while chain[-1] != 0:
        chain.append(int(model.body_parentid[chain[-1]]))
    meet = 0  # the index in ``chain`` of the lowest common body so far
    for body in model.geom_bodyid[pads]:
        while body not in chain:
            body = model.body_parentid[body]
        meet = max(meet, chain.index(body))
    return chain[meet]


def _settle_at(world: World, name: str, opening: float) -> None:
    """The fingers commanded to ``opening`` from home, the arm held, for :data:`SETTLE` s."""
    gripper = world.robot.arm(name).gripper
    world.reset()
    world.data.ctrl[gripper.actuators] = gripper.command_for(opening)
    for _ in range(round(SETTLE / world.model.opt.timestep)):
        mujoco.mj_step(world.model, world.data)


def _both_sides(world: World, name: str, field: str) -> Finding:
    gripper = world.robot.arm(name).gripper
    centres = []
    for opening in (gripper.lower, gripper.upper):
        _settle_at(world, name, opening)
        centres.append(_pad_centres(world, name))
    (closed_one, closed_other), (open_one, open_other) = centres
    line = (open_one - open_other) / np.linalg.norm(open_one - open_other)  # from finger to finger
    travel = np.abs([(open_one - closed_one) @ line, (open_other - closed_other) @ line])
    least = SIDE_TRAVEL * (gripper.upper - gripper.lower)
    return Finding(
        name,
        "gripper moves both fingers",
        bool((travel >= least).all()),
        f"closed to open, the sides' pads move {travel[0] * 1000:.1f} and {travel[1] * 1000:.1f} mm",
        "a finger that stays put has an actuator of its own that the gripper does not drive: leave "
        f"{field}.gripper.actuator out (the actuators of the fingers' joints are found) and give command a "
        "list per actuator",
    )


def _opening(world: World, name: str, field: str) -> Finding:
    gripper = world.robot.arm(name).gripper
    _settle_at(world, name, gripper.open)
    one, other = (np.asarray(side) for side in gripper.pads)
    gap = min(
        mujoco.mj_geomDistance(world.model, world.data, int(a), int(b), 1.0, None) for a in one for b in other
    )
    measured = gap / 2
    return Finding(
        name,
        "opening table",
        abs(measured - gripper.open) <= OPENING_SLACK,
        f"commanded to open {gripper.open * 1000:.1f} mm per finger, the pads open {measured * 1000:.1f}",
        f"measure the table on the model (besman robots gripper ROBOT) and paste it into {field}.gripper",
    )


def closed_on(world: World, name: str, item, along: float = 0.0) -> None:
    """The object floated (no gravity) between the open pads at the tool frame, shifted ``along`` its
    length (m: a bar held by one end), the fingers closed on it."""
    gripper = world.robot.arm(name).gripper
    gravity = world.model.opt.gravity.copy()
    world.model.opt.gravity[:] = 0.0
    try:
        _settle_at(world, name, gripper.open)
        position, rotation = _tool_frame(world, name)
        across = np.arctan2(rotation[1, 1], rotation[0, 1])  # the box's narrow side across the fingers
        turn = across if item.footprint[0] <= item.footprint[1] else across + np.pi / 2
        length = np.array([-np.sin(turn), np.cos(turn), 0.0])  # the object's y axis, once turned
        world.set_object_pose(
            item.name, position + along * length, [np.cos(turn / 2), 0.0, 0.0, np.sin(turn / 2)]
        )
        world.data.ctrl[gripper.actuators] = gripper.command_for(gripper.lower)
        for _ in range(round(SETTLE / world.model.opt.timestep)):
            mujoco.mj_step(world.model, world.data)
    finally:
        world.model.opt.gravity[:] = gravity


def _holds(world: World, name: str, item) -> Finding:
    closed_on(world, name, item)
    touching = Hand(world, world.robot.arm(name)).touching(item.name)
    sides = [side for side, touches in zip(("first", "second"), touching, strict=True) if not touches]
    return Finding(
        name,
        "pads close on the task's object",
        not sides,
        f"an object {item.narrowest * 1000:.0f} mm across, closed on at the tool frame: "
        + ("both sides' pads touch it" if not sides else f"the {' and '.join(sides)} side's pads do not"),
        "name as pads the geoms (or finger bodies) that touch what the hand holds, and put the tool frame "
        "between them",
    )


def _keeps_hold(world: World, name: str, item) -> Finding:
    """Closed on the object, then its weight on: after :data:`HOLD_SETTLE` s to settle in the grip, it must
    not creep down between the pads (a grip whose contacts cannot carry the weight slides on steadily)."""
    model, body = world.model, world.model.body(item.name).id
    saved = model.body_mass[body], model.body_inertia[body].copy()
    model.body_mass[body], model.body_inertia[body] = item.mass, item.inertia  # the family's heaviest
    try:
        closed_on(world, name, item)
        heights = settled_then_held(world, lambda: world.object_pose(item.name).position[2])
    finally:
        model.body_mass[body], model.body_inertia[body] = saved
    slid = max(float(heights[0] - heights[1]), 0.0)  # risen a hair in the grip: not slid
    return Finding(
        name,
        "holds the task's object up",
        slid <= HOLD_SLIDE,
        f"{item.mass:.2f} kg, held for {HOLD_TIME:g} s after {HOLD_SETTLE:g} s to settle: it slid "
        f"{slid * 1000:.1f} mm (at most {HOLD_SLIDE * 1000:.0f})",
        f"a grip that holds: contact options ({world.robot.description.file}: options, e.g. impratio 10 and "
        "elliptic cones), the pads' friction in the model, or a gripper actuator with more force",
    )


def settled_then_held(world: World, measure) -> tuple[float, float]:
    """``measure()`` after :data:`HOLD_SETTLE` s of simulation, and again :data:`HOLD_TIME` s later."""
    measured = []
    for seconds in (HOLD_SETTLE, HOLD_TIME):
        for _ in range(round(seconds / world.model.opt.timestep)):
            mujoco.mj_step(world.model, world.data)
        measured.append(measure())
    return measured[0], measured[1]


def _integrator(world: World, name: str, file) -> Finding:
    """Each joint of the arm and its gripper, on its own inertia at home (armature included), with its
    actuators' stiffness and damping and its own damping: stable under the model's integrator and timestep
    (MuJoCo's Euler takes an actuator's damping explicitly: a stiff servo on a light finger diverges)."""
    model, data = world.model, world.data
    arm = world.robot.arm(name)
    groups = [*arm.groups, arm.gripper.group]
    integrator = int(model.opt.integrator)
    euler_damping = not model.opt.disableflags & mujoco.mjtDisableBit.mjDSBL_EULERDAMP
    spelt = {value: key for key, value in CHOICES["integrator"].items()}[integrator]
    worst = None
    for joint in dict.fromkeys(j for group in groups for j in world.robot.group(group).joints):
        index = model.joint(joint).id
        inertia = joint_inertia(model, data, index)
        stiffness, servo_damping = servo_gains(model, index)
        own = float(model.dof_damping[model.jnt_dofadr[index]])
        growth = growth_per_step(
            integrator,
            model.opt.timestep,
            inertia,
            stiffness,
            servo_damping + own,
            own if euler_damping else 0.0,
        )
        if worst is None or growth > worst[0]:
            worst = (growth, joint, inertia, stiffness, servo_damping, own)
    growth, joint, inertia, stiffness, servo_damping, own = worst
    stable = growth <= 1.0 + 1e-9
    measured = (
        f"{spelt} at timestep {model.opt.timestep:g} s: the least stable joint, {joint} (inertia "
        f"{inertia:.3g} with armature, the actuators' stiffness {stiffness:.3g} and damping "
        f"{servo_damping:.3g}, its own damping {own:.3g}), "
        + ("settles" if stable else f"grows {growth:.2f} times a step: the simulation diverges")
    )
    fix = (
        f"set options.integrator \"implicit\" in {file} (MuJoCo's Euler takes the actuators' damping "
        "explicitly: damping x timestep / inertia above 2 diverges), or a smaller options.timestep"
    )
    return Finding(name, "the integrator keeps the joints stable", stable, measured, fix)


def _limits(world: World, name: str, file) -> Finding:
    """Each joint alone from home, far enough to reach its velocity limit (within its range), the lag of
    the measured joint behind its command watched every control cycle; a joint that lags is told by its
    cause in the model (:func:`_lag_cause`)."""
    config = ExecutorConfig()
    lags, speeds = [], []
    joints = Arm(world, name).joints
    for index in range(len(joints)):
        world.reset()
        executor = Executor(world, name)
        arm, start = executor.arm, executor.position.copy()
        speed, accel, jerk = arm.max_velocity[index], arm.max_acceleration[index], arm.max_jerk[index]
        wanted = speed * speed / accel + speed * accel / jerk  # to full speed and back
        up, down = arm.upper[index] - start[index], start[index] - arm.lower[index]
        target = start.copy()
        target[index] += min(wanted, 0.8 * up) if up >= down else -min(wanted, 0.8 * down)
        worst = [0.0, 0.0]

        def watch(index=index, worst=worst, executor=executor) -> None:
            behind = abs(executor.measured_position()[index] - executor.position[index])
            worst[0] = max(worst[0], behind)
            worst[1] = max(worst[1], abs(executor.stream.velocity[index]))

        executor.run(MoveTo("limits", target=target), timeout=10.0, observe=watch)
        # A move this short may end before the lag from the joint's damping and friction has built up; a
        # demo's longer one lags as much as it steadily does at the velocity limit.
        steady = steady_lag(*_servo(world, joints[index]), speed)
        lags.append(max(worst[0], steady))
        speeds.append(worst[1] if worst[0] >= steady else speed)
    allowed = LAG_SHARE * config.following_tolerance
    worst = int(np.argmax(lags))
    measured = (
        f"the largest lag, {joints[worst]}'s, {lags[worst]:.3f} at {speeds[worst]:.2f}/s "
        f"(at most {allowed:.3f}: the executor fails a motion at {config.following_tolerance})"
    )
    passed = lags[worst] <= allowed
    asks, fix = ("", "") if passed else _lag_cause(world, joints[worst], lags[worst], speeds[worst], file)
    return Finding(name, "joints follow their limits", passed, measured + (f"; {asks}" if asks else ""), fix)


def _servo(world: World, joint: str) -> tuple[float, float, float, float]:
    """The stiffness kp and the damping kv of ``joint``'s position actuator (kv 0 where the commands lead
    by kv / kp: ``velocity_feedforward``), and the joint's own damping and friction loss."""
    model = world.model
    index = model.joint(joint).id
    kp, kv = servo_gains(model, index)
    kv *= not world.robot.description.velocity_feedforward
    dof = model.jnt_dofadr[index]
    return kp, kv, float(model.dof_damping[dof]), float(model.dof_frictionloss[dof])


def _below(speed: float) -> float:
    """``speed`` rounded down to 0.01, strictly below it (a limit at the allowance lags just past it)."""
    return np.ceil(speed * 100 - 1) / 100


def _lag_cause(world: World, joint: str, lag: float, speed: float, file) -> tuple[str, str]:
    """Why ``joint`` lags ``lag`` at ``speed``, and what to change: (what the model asks of its actuator,
    the fix). At speed v a position servo of stiffness kp and damping kv, which must give the joint's
    friction loss f and damping d x v, lags (f + (d + kv) v) / kp (kv not where the commands lead by kv / kp:
    ``velocity_feedforward``), up to f / kp at rest (against the executor's arrival tolerance), drives it no
    faster than (force range - f) / d. The rest of the lag measured (inertia, gravity) stays at a lower
    speed, so the velocity suggested is one this check passes."""
    config = ExecutorConfig()
    allowed = LAG_SHARE * config.following_tolerance
    kp, kv, damping, friction = _servo(world, joint)
    force = force_limit(world.model, world.model.joint(joint).id)
    field = f"{file}: limits.{joint}.velocity"
    if kp <= 0 or not (damping or friction):  # the actuator's own damping, or a servo through a tendon
        fastest = speed * allowed / max(lag, 1e-9)  # the lag grows with the speed
        return "", (
            f"the model's actuators cannot drive {joint} that fast: a velocity limit of at most "
            f"{_below(fastest):.2f} ({field}), or velocity_feedforward where the actuators "
            "damp the joint's speed"
        )
    predicted = steady_lag(kp, kv, damping, friction, speed)
    rest = max(lag - predicted, 0.0)
    fastest = min(
        ((allowed - rest) * kp - friction) / (damping + kv) if damping + kv > 0 else np.inf,
        (force - friction) / damping if damping > 0 else np.inf,
    )
    if np.isinf(fastest):  # friction alone does not grow with the speed: what else does, in proportion
        fastest = speed * allowed / max(lag, 1e-9)
    gives = f"gives at most {force:.3g} (forcerange)" if np.isfinite(force) else "has no force limit"
    asks = (
        f"{joint}'s damping {damping:.3g} and friction loss {friction:.3g} need "
        f"{friction + damping * speed:.3g} at {speed:.2f}/s; its actuator {gives} and lags {predicted:.3f} "
        f"for it (kp {kp:.3g}), {friction / kp:.3f} at rest (it must arrive within "
        f"{config.arrival_tolerance})"
    )
    change = f"lower {joint}'s damping or frictionloss in the model, or raise its actuator's kp or forcerange"
    if not fastest > 0:
        return asks, f"{change}: no velocity limit is slow enough"
    return asks, f"{change}, or a velocity limit of at most {_below(fastest):.2f} ({field})"
