"""Pick and place's own checks of a robot (``besman robots check``, :meth:`PickPlace.robot_checks
<besman.tasks.pick_place.PickPlace.robot_checks>`), after the arm and gripper checks of
:mod:`besman.tasks.robot_check`, on the robot's first arm (the one that works alone):

- **areas**: the description gives the place area (``tasks.pick-place.places``), or the checks below are
  skipped.
- **home**: the home keyframe points the hand down (the tool frame's z axis), or inverse kinematics turns it
  down from there at the object area's middle: the planner starts inverse kinematics at home.
- **reach**: the arm reaches the object area (on the table) and the place area (on the shelf) top-down, at
  their corners and middles.
- **pick-place**: the arm picks the task's object at the middle of the object area and places it at the
  middle of the place area (the run without a seed, on a robot without a default configuration).
"""

from __future__ import annotations

from collections.abc import Iterator

import numpy as np

from besman.sim.arm import Arm
from besman.sim.manipulation import heights
from besman.sim.plans import DEFAULT_PLAN
from besman.sim.primitives import top_down
from besman.sim.world import World, tabletop_world
from besman.tasks.pick_place.scene import areas, the_object
from besman.tasks.robot_check import Finding

REACH_YAWS = np.radians([0.0, 90.0, 45.0, -45.0])  # hand yaws a reach is tried at (a cube's grasps)
HOME_TILT = 10.0  # deg the home's tool z axis may lean from straight down


def robot_checks(task, robot: str, description) -> Iterator[Finding]:
    """The module documentation's checks of ``task`` (pick-place) on ``robot`` (its ``description``), one
    finding at a time."""
    first = next(iter(description.arms), None)
    found = areas(robot)  # (object area, place area), or None
    if found is None:
        yield Finding(
            first or "-",
            "the task's areas",
            False,
            "the description gives no place area for pick-place: the reach and pick-place checks are skipped",
            f"add tasks.pick-place.places (x and y ranges on the shelf) to {description.file}",
        )
        return
    if first is None or description.arms[first].gripper is None:
        return
    values = task.default_values(robot)
    item = the_object(robot, values, None)
    world = tabletop_world((item,), robot=robot)
    reach, places = found
    grasp_z, _, place_z = heights(world, item, DEFAULT_PLAN)
    field = f"{description.file}: arms.{first}"
    checks = [
        lambda: _home(world, first, field, [*np.mean(reach, axis=1), grasp_z]),
        lambda: _reach(world, first, "object area", reach, grasp_z, f"{description.file}: tabletop.reach"),
        lambda: _reach(world, first, "place area", places, place_z, "the task's places"),
        lambda: _pick_place(world, values),
    ]
    for check in checks:
        world.reset()
        yield check()


def _home(world: World, name: str, field: str, middle) -> Finding:
    """The home's hand pointing down, or turned down from there by inverse kinematics without restarts at
    ``middle`` (the planner solves its first pose from home)."""
    arm = Arm(world, name)
    down = arm.site_pose(arm.home).rotation[:, 2]
    tilt = float(np.degrees(np.arccos(np.clip(-down[2], -1.0, 1.0))))
    turned = tilt <= HOME_TILT or arm.solve_ik(middle, top_down(0.0), initial=arm.home).success
    measured = f"the tool frame's z axis is {tilt:.0f} deg from straight down"
    if tilt > HOME_TILT:
        reached = "reaches" if turned else "does not reach"
        measured += f"; inverse kinematics from there {reached} the object area's middle hand down"
    return Finding(
        name,
        "home points the hand down",
        turned,
        measured,
        f"a home keyframe with the hand pointing down (the model's, or the description's home); if the hand "
        f"does point down there, turn the tool frame so that its z axis points out of the hand ({field}.tcp)",
    )


def _reach(world: World, name: str, area: str, bounds, z: float, field: str) -> Finding:
    arm = Arm(world, name)
    (x0, x1), (y0, y1) = bounds
    points = [(x0, y0), (x0, y1), (x1, y0), (x1, y1), ((x0 + x1) / 2, (y0 + y1) / 2)]
    missed = []
    for x, y in points:
        solved = [arm.solve_ik([x, y, z], top_down(yaw), initial=arm.home, restarts=4) for yaw in REACH_YAWS]
        if not any(result.success for result in solved):
            best = min(solved, key=lambda result: result.position_error)
            missed.append(f"({x:.2f}, {y:.2f}) by {best.position_error * 1000:.0f} mm")
    return Finding(
        name,
        f"reaches the {area} top-down",
        not missed,
        f"{len(points) - len(missed)} of its 5 corners and middle at z {z:.3f} m"
        + (f"; missed {', '.join(missed)}" if missed else ""),
        f"shrink the area to what the arm reaches ({field}) or move the robot (mount)",
    )


def _pick_place(world: World, values: dict) -> Finding:
    from besman.tasks.pick_place.episode import run_episode

    detail = run_episode(world, values, DEFAULT_PLAN)
    at, to = (np.round(values[key][:2], 3).tolist() for key in ("object", "place"))
    placed = "" if detail.placement_error is None else f": placed {detail.placement_error * 100:.1f} cm off"
    return Finding(
        world.robot.arm().name,
        "picks and places at the areas' middles",
        bool(detail.success),
        f"object at {at}, place {to}{placed}" + ("" if detail.success else f"; failed at {detail.message}"),
        "what the failed step's message says (the checks above find most causes one by one)",
    )
