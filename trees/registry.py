"""Templates and pools that tree files name as ``MODULE:NAME``, never imported because a file says so.

A leaf's ``template: my_skills:REACH`` or ``pool: my_skills:POOL`` names a Python object. Reading a file must
not run code the file chooses, so such a reference resolves only to

- an object registered in this process under that reference (:func:`register_template`,
  :func:`register_pool`), or
- an attribute of a module the user allowed (``load_tree(..., allow_modules=["my_skills"])``, or
  ``--allow-module my_skills`` on the commands that load trees), imported when the tree is built to run.

Anything else is refused with how to allow it. Checking a file (:func:`~besman.trees.files.check_tree`,
``besman tree check``) imports nothing: it checks the reference's form and that it is registered or its
module allowed.
"""

from __future__ import annotations

import importlib
import keyword
from collections.abc import Iterable, Iterator, Mapping
from typing import Any

from besman.core.errors import InputError

_TEMPLATES: dict[str, Any] = {}
_POOLS: dict[str, Mapping[str, Any]] = {}


def register_template(reference: str, template: Any) -> None:
    """Tree files of this process may name ``template`` (an object with ``instantiate(tau)``) as
    ``reference`` (``MODULE:NAME``) in a leaf's ``template``."""
    _parsed(reference)
    _check(reference, "template", template)
    _TEMPLATES[reference] = template


def register_pool(reference: str, pool: Mapping[str, Any]) -> None:
    """Tree files of this process may name ``pool`` (a mapping of names to templates) as ``reference``
    (``MODULE:NAME``) in a leaf's ``pool``."""
    _parsed(reference)
    _check(reference, "pool", pool)
    _POOLS[reference] = pool


def allowed_modules(names: Iterable[str]) -> frozenset[str]:
    """The modules of an allow-list, each checked to be a module name."""
    if isinstance(names, str):  # a lone name would be taken letter by letter
        raise InputError(f"allow_modules: a list of module names, not the string {names!r}")
    for name in names:
        if not (isinstance(name, str) and _is_module_name(name)):
            raise InputError(f"allow_modules: {name!r} is not a module name (identifiers joined by dots)")
    return frozenset(names)


class _Unimported(Mapping):
    """Stands for a template or pool of an allowed module while a file is only checked: as a pool it holds
    every name (itself), so the leaves' own checks of their other parameters still run."""

    def __getitem__(self, name: str) -> _Unimported:
        return self

    def __contains__(self, name: object) -> bool:
        return True

    def __iter__(self) -> Iterator[str]:
        return iter(())

    def __len__(self) -> int:
        return 0


UNIMPORTED = _Unimported()


def resolve(reference: str, kind: str, allowed: frozenset[str], *, imports: bool) -> Any:
    """The template or pool (``kind``) that ``reference`` names: registered, or the attribute of an allowed
    module - imported if ``imports``, else :data:`UNIMPORTED` stands for it."""
    module, attribute = _parsed(reference)
    registered = (_TEMPLATES if kind == "template" else _POOLS).get(reference)
    if registered is not None:
        return registered
    if module not in allowed:
        register = "register_template" if kind == "template" else "register_pool"
        raise InputError(
            f"{reference!r}: module {module!r} is not allowed; a tree file imports only modules you allow "
            f"(--allow-module {module}, or load_tree(..., allow_modules=[{module!r}])) or names a {kind} "
            f"registered with besman.trees.{register}"
        )
    if not imports:
        return UNIMPORTED
    try:
        found = getattr(importlib.import_module(module), attribute)
    except ImportError as error:
        raise InputError(f"{reference!r}: cannot import module {module!r} ({error})") from None
    except AttributeError:
        raise InputError(f"{reference!r}: module {module!r} has no {attribute!r}") from None
    _check(reference, kind, found)
    return found


def _is_module_name(text: str) -> bool:
    return all(part.isidentifier() and not keyword.iskeyword(part) for part in text.split("."))


def _parsed(reference: str) -> tuple[str, str]:
    module, colon, attribute = reference.partition(":") if isinstance(reference, str) else ("", "", "")
    if not (colon and _is_module_name(module) and attribute.isidentifier()):
        raise InputError(
            f"{reference!r} is not a reference MODULE:NAME (a module name of identifiers joined by dots, a "
            "colon, an identifier: my_skills:REACH)"
        )
    return module, attribute


def _check(reference: str, kind: str, value: Any) -> None:
    if kind == "pool" and not isinstance(value, Mapping):
        raise InputError(f"{reference!r} is not a pool (a mapping of names to templates)")
    if kind == "template" and not callable(getattr(value, "instantiate", None)):
        raise InputError(f"{reference!r} is not a template: it has no instantiate(tau)")
