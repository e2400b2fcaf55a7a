"""MkDocs hooks of besman's documentation.

- The API reference reads the sources as an installed ``besman`` would see them: the package's folders are
  mapped to its subpackages by ``pyproject.toml`` (``skills/`` is ``besman.skills``...), a layout that the
  reference's static analysis (griffe) cannot follow, so the build first assembles ``build/docs-src/besman``
  from links to those folders.
- ``<!-- besman-cli -->`` in a page becomes the command line's help, from the parser itself.
"""

from __future__ import annotations

import tomllib
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
SOURCES = ROOT / "build" / "docs-src"


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


def on_page_markdown(markdown: str, **_) -> str:
    if "<!-- besman-cli -->" not in markdown:
        return markdown
    return markdown.replace("<!-- besman-cli -->", _command_line())


def _command_line() -> str:
    from besman.cli import build_parser, commands

    return "\n".join(
        f"## `{' '.join(['besman', *path])}`\n\n```\n{parser.format_help().rstrip()}\n```\n"
        for path, parser in commands(build_parser())
    )
