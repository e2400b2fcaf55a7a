"""`besman pool`: what a skill template pool (a directory) holds."""

from __future__ import annotations

import argparse
import json
from pathlib import Path

from besman.core.errors import InputError


def _pool_ls(args: argparse.Namespace) -> int:
    from besman.skills.pool import PoolError, SkillTemplatePool

    pool = SkillTemplatePool(args.directory)
    if not Path(args.directory).is_dir():
        raise InputError(f"{args.directory}: no such pool directory")
    broken = 0
    for name in pool:
        try:
            template = pool[name]
        except PoolError as error:
            broken += 1
            print(f"{name}\tunreadable: {error}")
            continue
        box = ", ".join(f"{n} [{lo:g}, {hi:g}]" for n, (lo, hi) in template.box.as_dict().items())
        size = template.thetas.shape[1]
        print(f"{name}\t{template.task or '-'}\tK={len(template.taus)}\ttheta {size}\ttau {box}")
    return 1 if broken else 0


def _pool_show(args: argparse.Namespace) -> int:
    from besman.skills.pool import SkillTemplatePool, summary

    pool = SkillTemplatePool(args.directory)
    if args.name not in pool:
        raise InputError(
            f"{args.directory}: the pool has no template {args.name!r} (has: {', '.join(pool) or 'none'})"
        )
    facts = summary(pool[args.name])
    if args.json:
        print(json.dumps(facts, indent=2))
    else:
        for key, value in facts.items():
            if key != "hyperparameters":
                print(f"{key}\t{value}")
    return 0


def register(commands) -> None:
    """Adds this module's commands to the parser's subcommands."""
    pool = commands.add_parser("pool", help="inspect a skill template pool (a directory)")
    pool_commands = pool.add_subparsers(dest="pool_command", metavar="ACTION", required=True)
    pool_ls = pool_commands.add_parser("ls", help="the templates in a pool, one per line")
    pool_ls.add_argument("directory")
    pool_ls.set_defaults(handler=_pool_ls)
    pool_show = pool_commands.add_parser("show", help="one template: task, tau box, training set, kernel")
    pool_show.add_argument("directory")
    pool_show.add_argument("name")
    pool_show.add_argument("--json", action="store_true")
    pool_show.set_defaults(handler=_pool_show)
