"""`besman examples`: the examples installed with besman - where they are, and a copy to work with."""

from __future__ import annotations

import argparse
from pathlib import Path

from besman.core.errors import InputError


def _examples(args: argparse.Namespace) -> int:
    import os
    import shutil
    import tempfile

    from besman import examples
    from besman.core.storage import WriteError, write_error

    source = examples.path()
    if args.copy is None:
        print(source)
        for part in examples.CONTENTS:
            names = sorted(p.name for p in (source / part).iterdir() if not p.name.startswith((".", "_")))
            print(f"  {part}/: {', '.join(names)}")
        return 0
    folder = Path(args.copy)
    target = folder / "examples"
    if target.exists():
        raise InputError(f"--copy {folder}: {target} exists; nothing is copied over it")
    folder.mkdir(parents=True, exist_ok=True)
    # Copied beside the target first and renamed into place: a copy is whole or absent.
    staging = Path(tempfile.mkdtemp(dir=folder, prefix=".examples."))

    def copy(file: str, copied: str) -> None:
        # The first file that cannot be written stops the copy, named at its place in the target
        # (copytree would go on, filling a full disk, and then name every file in one huge error).
        try:
            shutil.copy2(file, copied)
        except OSError as error:
            raise write_error(target / Path(copied).relative_to(staging), error) from None

    try:
        for part in examples.CONTENTS:
            shutil.copytree(
                source / part, staging / part, ignore=shutil.ignore_patterns(".*", "__*"), copy_function=copy
            )
        os.rename(staging, target)
    except shutil.Error as error:  # a folder that could not be made (copytree collects those)
        _, copied, reason = error.args[0][0]
        raise WriteError(
            f"{target / Path(copied).relative_to(staging)}: cannot write it ({reason})"
        ) from None
    finally:
        shutil.rmtree(staging, ignore_errors=True)
    print(target)
    return 0


def register(commands) -> None:
    """Adds this module's commands to the parser's subcommands."""
    examples = commands.add_parser(
        "examples", help="the example trees, pools and recordings installed with besman (and a copy of them)"
    )
    examples.add_argument(
        "--copy", metavar="DIR", help="copy them to DIR/examples, where the README's commands find them"
    )
    examples.set_defaults(handler=_examples)
