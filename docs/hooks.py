"""MkDocs hooks of besman's documentation.

- The API reference reads the sources as an installed ``besman`` would see them: the package's folders are
  mapped to its subpackages by ``pyproject.toml`` (``skills/`` is ``besman.skills``...), a layout that the
  reference's static analysis (griffe) cannot follow, so the build first assembles ``build/docs-src/besman``
  from links to those folders.
- ``<!-- besman-cli -->`` in a page becomes the command line's help, from the parser itself, and
  ``<!-- besman-measurements -->`` the measurements of every demo's run summary, from the gallery itself.
- Pictures that live beside what they show, outside ``docs/`` (``EXTRA_FILES``), are added to the site at
  their path in the repository, so a page links them as ``examples/pools/pick_place/summary.png``.
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
EXTRA_FILES = ("examples/pools/pick_place/summary.png",)


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
    """A table per demo (and one for ``besman run``) of the keys of its summary's ``measurements``."""
    from besman.trees.gallery import DEMOS
    from besman.trees.tabletop import MEASUREMENTS

    runs = [("`besman run` (a tree on a tabletop)", MEASUREMENTS)]
    runs += [(f"`besman demo {demo.name}`", demo.measurements) for demo in DEMOS.values()]
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
