"""MkDocs hooks of besman's documentation.

- The API reference reads the sources as an installed ``besman`` would see them: the package's folders are
  mapped to its subpackages by ``pyproject.toml`` (``skills/`` is ``besman.skills``...), a layout that the
  reference's static analysis (griffe) cannot follow, so the build first assembles ``build/docs-src/besman``
  from links to those folders.
- ``<!-- besman-cli -->`` in a page becomes the command line's help, from the parser itself, and
  ``<!-- besman-measurements -->`` the measurements of every task's run summary, from the task registry.
- Pictures that live beside what they show, outside ``docs/`` (``EXTRA_FILES``), are added to the site at
  their path in the repository, so a page links them as ``examples/pools/pick_place_aila/summary.png``.
"""

from __future__ import annotations

import tomllib
from pathlib import Path
from typing import TYPE_CHECKING

if TYPE_CHECKING:
    from mkdocs.config.defaults import MkDocsConfig
    from mkdocs.structure.files import Files

ROOT = Path(__file__).resolve().parents[1]
SOURCES = ROOT / "build" / "docs-src"
EXTRA_FILES = ("examples/pools/pick_place_aila/summary.png",)


def on_startup(**_) -> None:
    mapping = tomllib.loads((ROOT / "pyproject.toml").read_text())["tool"]["setuptools"]["package-dir"]
    package = SOURCES / "besman"
    package.mkdir(parents=True, exist_ok=True)
    for name, folder in mapping.items():
        if name == "besman":
            for path in (ROOT / folder).iterdir():
                link = package / path.name
                if not link.is_symlink() and not link.exists():
                    link.symlink_to(path)
            continue
        link = package / name.removeprefix("besman.")
        if not link.is_symlink():
            link.symlink_to(ROOT / folder)


def on_files(files: Files, config: MkDocsConfig, **_) -> Files:
    from mkdocs.structure.files import File

    for path in EXTRA_FILES:
        files.append(File.generated(config, path, abs_src_path=str(ROOT / path)))
    return files


def on_page_markdown(markdown: str, **_) -> str:
    generated = {"<!-- besman-cli -->": _command_line, "<!-- besman-measurements -->": _measurements}
    for marker, text in generated.items():
        if marker in markdown:
            markdown = markdown.replace(marker, text())
    return markdown


def _measurements() -> str:
    """A table per task of the keys of its summary's ``measurements`` (its demo and every ``besman run`` of
    a tree on it measure the same)."""
    from besman.tasks import TASKS

    runs = [
        (
            f"task `{entry.name}` (`besman run` of a tree on it"
            + (f", `besman demo {entry.name}`)" if entry.tree is not None else ")"),
            entry.measurements,
        )
        for entry in TASKS.values()
    ]
    return "\n".join(
        f"{title}:\n\n| key | meaning |\n|---|---|\n"
        + "".join(f"| `{key}` | {meaning} |\n" for key, meaning in measurements.items())
        for title, measurements in runs
    )


def _command_line() -> str:
    from besman.cli import build_parser, commands

    return "\n".join(
        f"## `{' '.join(['besman', *path])}`\n\n```\n{parser.format_help().rstrip()}\n```\n"
        for path, parser in commands(build_parser())
    )
