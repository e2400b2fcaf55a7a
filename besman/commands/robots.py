"""`besman robots`: list, describe and render the robot models."""

from __future__ import annotations

import argparse
import json
import sys


def _robot_table(name: str) -> dict:
    """The JSON-ready description of a robot: groups, and per joint its limits and actuator."""
    from besman.robots import load

    robot = load(name)
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
        "model": str(robot.description.model_file),
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
        "joints": joints,
    }


def _robots_list(args: argparse.Namespace) -> int:
    from besman.robots import available, load

    for name in available():
        print(f"{name}\t{load(name).description.title}")
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
    render.add_argument("--width", type=int, default=960)
    render.add_argument("--height", type=int, default=720)
    render.add_argument("--keyframe", default=None, help="keyframe to show (default: home)")
    render.set_defaults(handler=_robots_render)
