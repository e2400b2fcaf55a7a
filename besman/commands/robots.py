"""`besman robots`: list, describe and render the robot models."""

from __future__ import annotations

import argparse
import json
import sys

from besman.commands.options import COUNT, integer
from besman.core.errors import InputError


def _robot_table(name: str) -> dict:
    """The JSON-ready description of a robot: its model, groups, arms, and per joint its limits."""
    from besman.robots import load
    from besman.robots.assembly import model_path

    robot = load(name, meshes=False)  # the table reads joints, actuators and the description
    description = robot.description
    joints = []
    for group in robot.groups.values():
        for i, joint in enumerate(group.joints):
            joints.append(
                {
                    "group": group.name,
                    "name": joint,
                    "lower": float(group.lower[i]),
                    "upper": float(group.upper[i]),
                    "velocity": float(group.velocity[i]),
                    "acceleration": float(group.acceleration[i]),
                    "jerk": float(group.jerk[i]),
                }
            )
    return {
        "name": robot.name,
        "title": robot.description.title,
        "model": str(model_path(description.model, description.folder, str(description.file))),
        "attached": [
            str(model_path(part.model, description.folder, str(description.file)))
            for part in description.attach
        ],
        "nq": robot.model.nq,
        "nu": robot.model.nu,
        "timestep": robot.model.opt.timestep,
        "groups": {
            group.name: {
                "joints": list(group.joints),
                "actuators": list(group.actuators),
                "site": group.site,
                "equalities": list(group.equalities),
            }
            for group in robot.groups.values()
        },
        "arms": {
            arm.name: {
                "groups": list(arm.groups),
                "tcp": arm.tcp,
                "gripper": None
                if arm.gripper is None
                else {
                    "actuator": [robot.model.actuator(a).name for a in arm.gripper.actuators],
                    "opening_m": [arm.gripper.lower, arm.gripper.upper],
                    "open_m": arm.gripper.open,
                },
            }
            for arm in robot.arms.values()
        },
        "joints": joints,
    }


def _robots_list(args: argparse.Namespace) -> int:
    from besman.robots import available, describe

    for name in available():
        print(f"{name}\t{describe(name).title}")
    return 0


def _robots_show(args: argparse.Namespace) -> int:
    table = _robot_table(args.name)
    if args.json:
        print(json.dumps(table, indent=2))
        return 0
    from rich.console import Console
    from rich.table import Table

    view = Table(title=f"{table['name']}: {table['title']}")
    for column in ("group", "joint", "lower", "upper", "velocity", "acceleration", "jerk"):
        view.add_column(column, justify="left" if column in ("group", "joint") else "right")
    for joint in table["joints"]:
        view.add_row(
            joint["group"],
            joint["name"],
            *(f"{joint[key]:.4g}" for key in ("lower", "upper", "velocity", "acceleration", "jerk")),
        )
    console = Console(width=None if sys.stdout.isatty() else 120)
    console.print(view)
    console.print("units: rad or m; velocity per s, acceleration per s^2, jerk per s^3")
    for name, group in table["groups"].items():
        console.print(f"{name}: site={group['site']}, actuators={', '.join(group['actuators']) or '-'}")
    return 0


def _robots_render(args: argparse.Namespace) -> int:
    from besman.robots import load
    from besman.robots.render import png_path, render, save_png

    out = png_path(args.out)  # fail before the work, not after it
    image = render(load(args.name), width=args.width, height=args.height, keyframe=args.keyframe)
    print(save_png(image, out))
    return 0


def _robots_gripper(args: argparse.Namespace) -> int:
    import numpy as np

    from besman.robots import load
    from besman.robots.gripper import measure_openings

    if not 2 <= args.steps <= 256:
        raise InputError(f"--steps must be between 2 and 256, got {args.steps}")
    robot = load(args.name)
    gripper = robot.arm(args.arm).gripper
    if gripper is None:
        raise InputError(f"robot {robot.name!r}: arm {robot.arm(args.arm).name!r} has no gripper")
    # From the table's one end to the other, every actuator at once (rows: one command per actuator).
    commands = np.linspace(gripper.command[0], gripper.command[-1], args.steps)
    openings = measure_openings(robot, args.arm, commands)
    columns = [[round(float(c), 4) for c in column] for column in commands.T]
    table = {
        "opening": [round(float(v), 5) for v in openings],
        "command": columns[0] if len(columns) == 1 else columns,
    }
    print(json.dumps(table))
    return 0


def _robots_check(args: argparse.Namespace) -> int:
    """Each check of :mod:`besman.tasks.robot_check` as it finishes: a line each (or JSON lines); 1 if
    any failed."""
    from besman.tasks.robot_check import check_robot

    failed = 0
    for finding in check_robot(args.name):
        failed += not finding.passed
        if args.json:
            print(json.dumps(finding.__dict__), flush=True)
            continue
        verdict = "ok  " if finding.passed else "FAIL"
        print(f"{verdict} {finding.arm}: {finding.check}: {finding.measured}", flush=True)
        if not finding.passed:
            print(f"     to change: {finding.fix}", flush=True)
    if not args.json:
        print("all checks passed" if not failed else f"{failed} check(s) failed", flush=True)
    return 1 if failed else 0


def register(commands) -> None:
    """Adds this module's commands to the parser's subcommands."""
    robots = commands.add_parser("robots", help="list, describe and render the robot models")
    robots.set_defaults(handler=_robots_list)
    robot_commands = robots.add_subparsers(dest="robots_command", metavar="ACTION")
    show = robot_commands.add_parser("show", help="joint table of a robot: group, name, limits, speed")
    show.add_argument("name")
    show.add_argument("--json", action="store_true", help="print JSON instead of a table")
    show.set_defaults(handler=_robots_show)
    render = robot_commands.add_parser("render", help="offscreen MuJoCo picture of a robot's scene")
    render.add_argument("name")
    render.add_argument("--out", required=True, help="output PNG file")
    render.add_argument("--width", type=COUNT, default=960)
    render.add_argument("--height", type=COUNT, default=720)
    render.add_argument("--keyframe", default=None, help="keyframe to show (default: home)")
    render.set_defaults(handler=_robots_render)
    gripper = robot_commands.add_parser(
        "gripper",
        help="measure a gripper's opening (m per finger) across its commands: the description's table",
    )
    gripper.add_argument("name")
    gripper.add_argument("--arm", default=None, help="the arm (default: the robot's first)")
    gripper.add_argument(
        "--steps", type=integer(2), default=18, help="how many commands, evenly spaced (default 18)"
    )
    gripper.set_defaults(handler=_robots_gripper)
    check = robot_commands.add_parser(
        "check",
        help="check a robot for the tabletop tasks (home, tool frame, gripper, reach, limits, one "
        "pick and place), a line per check with what to change",
    )
    check.add_argument("name", help="a robot's name or folder")
    check.add_argument("--json", action="store_true", help="a JSON line per check")
    check.set_defaults(handler=_robots_check)
