"""The skill templates a leaf names, checked before any work.

A leaf that takes its motion from a pool (``pool`` and a template name) opens that template when the tree is
built - reading its files verifies their checksums and schema - so that a damaged or missing entry stops the
tree before its first tick, with the leaf, the pool and the reason, instead of failing seconds into an
episode with the box in the hand. When the leaf is set up on a robot, the template must have been learned on
that robot (joint-space primitives do not move between arms) and for the tau the leaf gives it.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from typing import Any

from besman.core.errors import BesmanError, InputError


def check_template(name: str, pool: Mapping[str, Any] | None, template: str | None) -> None:
    """Leaf ``name``'s pool and template name, both or neither; the template in the pool and whole."""
    if (pool is None) != (template is None):
        raise InputError(f"{name}: a learned motion needs both a pool and a template name")
    if pool is None:
        return
    where = getattr(pool, "directory", "the pool")
    if template not in pool:
        raise InputError(f"{name}: {where} has no template {template!r} (has: {', '.join(pool) or 'none'})")
    try:
        pool[template]
    except BesmanError as error:
        raise InputError(f"{name}: template {template!r} of {where} cannot be used: {error}") from None


def check_template_fits(name: str, template: Any, robot: str, tau_names: Sequence[str]) -> None:
    """Leaf ``name``'s template was learned on ``robot`` (as far as its provenance says) and takes the tau
    columns ``tau_names``."""
    learned_on = (getattr(template, "provenance", None) or {}).get("robot")
    if learned_on is not None and learned_on != robot:
        raise InputError(
            f"{name}: template {template.name!r} was learned on {learned_on!r}, this run is on {robot!r} "
            "(besman run --pool POOL takes a pool learned on it)"
        )
    names = tuple(template.box.names)
    if names != tuple(tau_names):
        raise InputError(
            f"{name}: template {template.name!r} takes tau ({', '.join(names)}), this leaf gives "
            f"({', '.join(tau_names)})"
        )
