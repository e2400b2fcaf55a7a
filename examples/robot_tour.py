"""A tour of besman's robot models: AILA reaches over a table, the PA-10 throws a ball.

    python examples/robot_tour.py [--out out/]

For each robot it checks that the home pose holds, shows the kinematics at work and renders a picture.
"""

from __future__ import annotations

import argparse
import math
import os
from pathlib import Path

os.environ.setdefault("MUJOCO_GL", "egl")  # offscreen rendering; must precede `import mujoco`

import mujoco
import numpy as np
from rich.console import Console

import besman.robots as robots
from besman.robots.render import render, save_png
from besman.skills import quaternion

console = Console()


def hold_home(robot: robots.Robot, seconds: float = 2.0) -> float:
    """Largest site drift (m) while the position actuators hold the home keyframe."""
    data = robot.make_data()
    start = data.site_xpos.copy()
    for _ in range(round(seconds / robot.model.opt.timestep)):
        mujoco.mj_step(robot.model, data)
    return float(np.linalg.norm(data.site_xpos - start, axis=1).max())


def aila_reaches_over_a_table(aila: robots.Robot) -> None:
    down = np.array([0.0, math.sqrt(0.5), math.sqrt(0.5), 0.0])  # approach -z, fingers close along x
    grid = [(x, y, 0.90) for x in (0.40, 0.45, 0.50, 0.55) for y in (-0.40, -0.30, -0.20, -0.10, 0.0)]
    results = [robots.solve_ik(aila, "right_arm", target, down) for target in grid]
    reached = sum(result.success for result in results)
    worst_mm = 1e3 * max(result.position_error for result in results)
    worst_deg = math.degrees(max(result.orientation_error for result in results))
    console.print(
        f"  right arm, top-down grasps over a table: {reached}/{len(grid)} reached "
        f"(worst {worst_mm:.3f} mm, {worst_deg:.3f} deg)"
    )
    far = robots.solve_ik(aila, "right_arm", [3.5, -0.2, 1.0], down)
    console.print(f"  a target 3 m away: {far.message}")


def pa10_throws(pa10: robots.Robot) -> None:
    """A step command swings shoulder, elbow and wrist forward (no motion limits yet); the weld switches
    off mid-swing and the ball flies. Reports the landing point."""
    model, data = pa10.model, pa10.make_data()
    arm = pa10.group("arm")
    weld = model.equality(pa10.group("release").equalities[0]).id
    ball = model.body("ball").id
    floor = model.geom("floor").id
    swing_from, swing_to = np.array([0, -0.6, 0, -1.0, 0, -0.6, 0]), np.array([0, 0.3, 0, 0.4, 0, 0.4, 0])
    data.qpos[arm.qpos_indices] = data.ctrl[arm.actuator_indices] = swing_from
    mujoco.mj_forward(model, data)
    holder = data.site("ball_holder")
    data.qpos[7:10] = holder.xpos  # the ball follows the hand to the new start pose
    data.qpos[10:14] = quaternion.from_matrix(holder.xmat.reshape(3, 3))
    data.ctrl[arm.actuator_indices] = swing_to
    released_at = None
    while data.time < 5.0:
        mujoco.mj_step(model, data)
        if released_at is None and data.time >= 0.09:  # mid-swing, ball rising
            data.eq_active[weld] = 0
            released_at = data.xpos[ball].copy()
        if released_at is not None and any(
            {c.geom1, c.geom2} == {floor, model.body_geomadr[ball]} for c in data.contact[: data.ncon]
        ):
            landing = data.xpos[ball]
            console.print(
                f"  released at ({released_at[0]:.2f}, {released_at[1]:.2f}, {released_at[2]:.2f}) m, "
                f"landed at ({landing[0]:.2f}, {landing[1]:.2f}) m after {data.time:.2f} s"
            )
            return
    console.print("  the ball never landed")


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--out", type=Path, default=Path("out"), help="folder for the pictures")
    args = parser.parse_args()
    for name in robots.available():
        robot = robots.load(name)
        console.rule(f"{name}: {robot.description.title}")
        sizes = ", ".join(f"{group.name} ({group.size})" for group in robot.groups.values())
        console.print(f"  {robot.model.nq} qpos, {robot.model.nu} actuators; groups: {sizes}")
        console.print(f"  home pose held for 2 s: largest site drift {1e3 * hold_home(robot):.4f} mm")
        if name == "aila":
            aila_reaches_over_a_table(robot)
        if name == "pa10":
            pa10_throws(robot)
        picture = save_png(render(robot), args.out / f"{name}.png")
        console.print(f"  picture: {picture}")


if __name__ == "__main__":
    main()
