"""AILA picks a box from the table and places it on the shelf with its right arm (and waist).

tau = (object x, object y, place x, place y): where the box stands on the table and where it must end up
on the shelf board, inside :data:`PICK_PLACE_BOUNDS`:

- object box: x in [0.45, 0.62] m, y in [-0.15, 0.00] m on the table (top 0.78 m), in front of the robot;
- place box: x in [0.45, 0.62] m, y in [-0.48, -0.34] m on the shelf board (top 0.90 m) to its right.

Both boxes lie where the right arm, turning the waist, reaches top-down grasps and the poses above them
with every joint at least 5 % of its range away from its limits for some grasp yaw (scanned on a grid).

The episode is a scripted sequence of joint-space movement primitives executed by the Ruckig executor
(straight vertical moves are DMPs imitating inverse-kinematics solutions along the line): open the gripper,
approach above the object, descend, grasp (close; a grasp is required), lift, transport above the place,
place, release, retreat. Before moving, the plan picks for grasp and place the hand yaw (across a pair of
the box's faces) for which every pose is reachable and collision-free and the vertical moves stay close to
a straight line (5 mm near the box), keeping farthest from the joint limits. theta tunes the plan
(:class:`PickPlacePlan`); ``default_theta()`` is the hand-made plan.

Success: the box was lifted at least 5 cm and carried in the hand until the release (not dropped), then
stands upright (tilt < 10 deg) on the shelf within 2 cm of the place target. Metrics per episode: placement
error, simulated time, largest contact force on the box, and which step failed and why.
"""

from __future__ import annotations

import math
from dataclasses import astuple, dataclass, fields

import mujoco
import numpy as np

import besman.robots as robots
from besman.sim.evaluation import Evaluation, check_backend, evaluate_in_processes, evaluate_on_ray
from besman.sim.executor import (
    Executor,
    FollowReference,
    GripperMotion,
    Motion,
    MotionStatus,
    limit_violations,
)
from besman.sim.primitives import point_to_point, straight_line, top_down
from besman.sim.tasks import TaskBounds
from besman.sim.world import DEFAULT_BOX, SHELF, TABLE, GraspableObject, World, tabletop_world
from besman.skills import Trajectory
from besman.skills.validation import finite_array

PICK_PLACE_BOUNDS = TaskBounds(
    ("object_x", "object_y", "place_x", "place_y"), (0.45, -0.15, 0.45, -0.48), (0.62, 0.00, 0.62, -0.34)
)
FAILURE_REWARD = -1.0
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
class PickPlaceDetail:
    """One episode's outcome and metrics."""

    success: bool
    grasped: bool  # the box was grasped and lifted
    placement_error: float | None  # m, horizontal distance of the box from the place target after release
    tilt_degrees: float | None
    sim_time: float
    max_contact_force: float  # N, largest normal force on the box
    failed_step: str | None
    message: str
    limit_violations: tuple[str, ...] = ()  # commanded joint states beyond a limit (from the command log)


@dataclass(frozen=True)
class PickPlaceConfig:
    """Everything that defines the task; ``build()`` makes it (also on Ray workers)."""

    item: GraspableObject = DEFAULT_BOX

    def build(self) -> PickPlaceTask:
        return PickPlaceTask(self)


class PickPlaceTask:
    """The pick-and-place task; see the module documentation."""

    bounds = PICK_PLACE_BOUNDS

    def __init__(self, config: PickPlaceConfig = PickPlaceConfig()) -> None:
        self.config = config
        self.world = tabletop_world((config.item,))

    @staticmethod
    def default_theta() -> np.ndarray:
        return PickPlacePlan().theta()

    @property
    def n_params(self) -> int:
        return len(fields(PickPlacePlan))

    # -- one episode ---------------------------------------------------------------------------------------

    def episode(self, tau, theta=None, *, world: World | None = None) -> PickPlaceDetail:
        """Runs one pick-and-place episode in ``world`` (default: the task's own) and measures it."""
        tau = self.bounds.check(tau)[0]
        plan = PickPlacePlan.from_theta(self.default_theta() if theta is None else theta)
        return run_episode(world or self.world, self.config.item, tau, plan)

    def evaluate(self, thetas, taus, *, backend: str = "threads") -> Evaluation:
        """Episodes for thetas (N, 6) and taus (N, 4): reward = -placement error (m) on success, else -1;
        details are :class:`PickPlaceDetail`. With ``backend="threads"`` the episodes run on all local
        cores in worker processes (the control loop is Python: threads would wait on each other), with
        ``"ray"`` on a Ray cluster."""
        check_backend(backend)
        thetas = finite_array("theta", thetas)
        thetas = thetas[None] if thetas.ndim == 1 else thetas
        for theta in thetas:
            PickPlacePlan.from_theta(theta)  # reject bad plans before any work starts
        taus = self.bounds.check(taus, n=len(thetas))
        if backend == "ray":
            return evaluate_on_ray(self.config, thetas, taus)
        return evaluate_in_processes(self.config, thetas, taus)

    def evaluate_locally(self, thetas: np.ndarray, taus: np.ndarray) -> Evaluation:
        """The episodes one after the other in this process, in the task's own world."""
        details = tuple(
            run_episode(self.world, self.config.item, tau, PickPlacePlan.from_theta(theta))
            for theta, tau in zip(thetas, taus, strict=True)
        )
        rewards = np.array([-d.placement_error if d.success else FAILURE_REWARD for d in details])
        return Evaluation(rewards, details)


@dataclass(frozen=True)
class _Leg:
    """A planned stretch of an episode: three hand poses of one orientation, the joint configurations that
    reach them, and the references of the two straight moves between them."""

    configurations: tuple[np.ndarray, np.ndarray, np.ndarray]
    references: tuple[Trajectory, Trajectory]
    clearance: float  # smallest distance to a joint limit along the references, as a fraction of the range


# How far (m) the hand may stray from the straight line in each vertical move: near the box the fingers
# have 1.5 cm on either side; lifting and retreating only need to stay clear of the furniture.
MAX_DEVIATION = {"descend": 0.005, "place": 0.005, "lift": 0.02, "retreat": 0.02}


def _plan_leg(
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
        orientation, configurations, qpos = top_down(yaw), [], executor.full_qpos(start)
        for index, position in enumerate(positions):
            result = robots.solve_ik(
                executor.world.robot,
                executor.groups,
                position,
                orientation,
                site=executor.site,
                initial_qpos=qpos,
                restarts=4 if index == 0 else 0,
                joint_weights=executor.max_acceleration,
            )
            if not result.success or executor.collisions(result.qpos, allowed):
                break
            configurations.append(result.qpos)
            qpos[executor.qpos_indices] = result.qpos
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
                _deviation(executor, reference, a, b) < MAX_DEVIATION[name]
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
                    best = _Leg(tuple(configurations), references, clearance)
    return best


def _site_path(executor: Executor, reference: Trajectory, samples: int = 20) -> np.ndarray:
    """Positions of the executor's site along a joint reference (about ``samples`` of them)."""
    return np.array(
        [
            robots.forward_kinematics(executor.world.robot, executor.full_qpos(q), executor.site).position
            for q in reference.positions[:: max(1, len(reference.times) // samples)]
        ]
    )


def _deviation(executor: Executor, reference: Trajectory, start: np.ndarray, end: np.ndarray) -> float:
    """Largest distance of the site's path along a joint reference from the straight segment start-end."""
    path = _site_path(executor, reference)
    direction = (end - start) / np.linalg.norm(end - start)
    offsets = path - start
    return float(np.linalg.norm(offsets - np.outer(offsets @ direction, direction), axis=1).max())


def run_episode(world: World, item: GraspableObject, tau: np.ndarray, plan: PickPlacePlan) -> PickPlaceDetail:
    """Resets ``world``, places the box at tau's object position, plans and runs the scripted sequence."""
    world.reset()
    object_xy, place_xy = tau[:2], tau[2:]
    world.place_on(item.name, TABLE.name, *object_xy)
    executor = Executor(world)
    grasp_z = TABLE.height + item.half_height + plan.grasp_height
    carry_z = SHELF.height + plan.clearance + item.half_height + plan.grasp_height
    place_z = SHELF.height + plan.release_height + item.half_height + plan.grasp_height
    pick = _plan_leg(
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
    if pick is None:
        return _failure(world, "plan", "no reachable, collision-free top-down grasp of the object")
    put = _plan_leg(
        executor,
        pick.configurations[-1],
        [np.r_[place_xy, carry_z], np.r_[place_xy, place_z], np.r_[place_xy, place_z + plan.approach_height]],
        ("place", "retreat"),
        plan.descend_time,
        allowed=(item.name,),
    )
    if put is None:
        return _failure(world, "plan", "no reachable, collision-free top-down placement at the target")
    transport = executor.primitive_reference(
        point_to_point(
            "transport", pick.configurations[-1], put.configurations[0], executor, plan.transport_time
        ),
        start=pick.configurations[-1],
    )
    # The joint-space transport cannot run into a joint limit, but its hand path must stay over the shelf.
    lowest = float(_site_path(executor, transport, 40)[:, 2].min())
    if lowest - item.half_height - plan.grasp_height < SHELF.height + 0.01:
        return _failure(world, "plan", f"the transport would sweep the box {lowest:.3f} m low over the shelf")
    approach = executor.primitive_reference(
        point_to_point("approach", executor.position, pick.configurations[0], executor)
    )
    steps = [
        GripperMotion("open", opening=OPEN),
        FollowReference("approach", reference=approach),
        FollowReference("descend", reference=pick.references[0]),
        GripperMotion("grasp", opening=0.0, expect_grasp=True, grasp_object=item.name),
        FollowReference("lift", reference=pick.references[1]),
        FollowReference("transport", reference=transport),
        FollowReference("place", reference=put.references[0]),
        GripperMotion("release", opening=OPEN),
        FollowReference("retreat", reference=put.references[1]),
    ]
    monitor = _BoxMonitor(world, item.name, executor)
    for motion in steps:
        _run(executor, motion, monitor)
        if motion.status is not MotionStatus.SUCCEEDED:
            return _failure(world, motion.name, motion.message, monitor)
        if motion.name in ("lift", "transport", "place") and not executor.holds(item.name):
            return _failure(world, motion.name, "the box slipped out of the hand", monitor)
        if motion.name == "lift":
            if monitor.highest < TABLE.height + item.half_height + 0.05:
                return _failure(world, motion.name, "the box was not lifted", monitor)
            monitor.grasped = True
    for _ in range(round(0.3 / world.model.opt.timestep)):  # let the box settle
        mujoco.mj_step(world.model, world.data)
        monitor.update()
    pose = world.object_pose(item.name)
    error = float(np.linalg.norm(pose.position[:2] - place_xy))
    tilt = math.degrees(math.acos(min(1.0, abs(pose.rotation[2, 2]))))
    on_shelf = abs(pose.position[2] - (SHELF.height + item.half_height)) < 0.01
    success = bool(error <= 0.02 and tilt < 10.0 and on_shelf)
    message = (
        "placed"
        if success
        else (
            f"placed {error * 100:.1f} cm from the target, tilted {tilt:.1f} deg"
            + ("" if on_shelf else ", off the shelf")
        )
    )
    violations = tuple(limit_violations(executor.log, executor))
    return PickPlaceDetail(
        success,
        True,
        error,
        tilt,
        float(world.data.time),
        monitor.max_force,
        None if success else "place",
        message,
        violations,
    )


def _run(executor: Executor, motion: Motion, monitor: _BoxMonitor, timeout: float = 15.0) -> Motion:
    executor.start(motion)
    deadline = executor.time + timeout
    while motion.status is MotionStatus.RUNNING:
        if executor.time >= deadline:
            motion.finish(MotionStatus.FAILED, f"timed out after {timeout:g} s")
            break
        executor.tick()
        monitor.update()
    return motion


class _BoxMonitor:
    """Tracks the box's highest point, the largest normal contact force on it, and whether it was grasped."""

    def __init__(self, world: World, name: str, executor: Executor) -> None:
        self.world, self.executor = world, executor
        self.grasped = False
        self.body = world.model.body(name).id
        self.highest = float(world.data.xpos[self.body][2])
        self.max_force = 0.0
        self._force = np.empty(6)

    def update(self) -> None:
        model, data = self.world.model, self.world.data
        self.highest = max(self.highest, float(data.xpos[self.body][2]))
        for i in range(data.ncon):
            contact = data.contact[i]
            if self.body in (model.geom_bodyid[contact.geom1], model.geom_bodyid[contact.geom2]):
                mujoco.mj_contactForce(model, data, i, self._force)
                self.max_force = max(self.max_force, float(self._force[0]))


def _failure(world: World, step: str, message: str, monitor: _BoxMonitor | None = None) -> PickPlaceDetail:
    time = float(world.data.time)
    if monitor is None:
        return PickPlaceDetail(False, False, None, None, time, 0.0, step, f"{step}: {message}")
    violations = tuple(limit_violations(monitor.executor.log, monitor.executor))
    return PickPlaceDetail(
        False, monitor.grasped, None, None, time, monitor.max_force, step, f"{step}: {message}", violations
    )
