"""The tasks: one module (or small package) per task, and the registry that every part of besman reads.

A task (:class:`~besman.tasks.base.Task`) says in one place what it is, what is randomised and what counts
as success; its task values tau per robot; which robots it fits; the world it builds; its default tree file;
the one rule that judges a run (demos, ``besman run``, learning rewards and benchmarks alike); its batched
evaluate for policy search; and the building blocks it learns. :data:`TASKS` holds every task of this
package - a module that defines ``TASKS`` (a tuple of tasks) is registered as it is added, so adding a task
is adding its module - and those of installed distributions that name a module with ``TASKS`` under the
entry point group ``besman.tasks`` (the documentation's "Add a task" page); a plugin that does not load, or
a task of one whose name is taken (besman's own tasks keep theirs), is left out with a
:class:`~besman.core.errors.PluginWarning` naming its distribution. A demo is a task run with its
default tree and a seed (:mod:`besman.tasks.running`); a run recorded as a dataset's episode is
:mod:`besman.tasks.recording`'s.

``besman tasks``, ``besman demo``, ``besman run``, ``besman learn`` and the experiments find tasks here.
"""

from __future__ import annotations

import importlib
import pkgutil
from collections.abc import Iterator
from types import ModuleType

from besman.core.errors import UnknownNameError
from besman.core.plugins import plugin_modules, warn_plugin
from besman.tasks.base import Task

DEFAULT = "pick-place"  # the task of ``besman demo`` without a name, and of ``besman learn``
# Modules of this package that are not tasks.
FRAMEWORK = ("base", "environment", "episodes", "frames", "recording", "robot_check", "running", "session")


ENTRY_POINTS = "besman.tasks"  # the group under which other distributions name their task modules


def _builtin() -> Iterator[ModuleType]:
    """This package's task modules."""
    for module in pkgutil.iter_modules(__path__):
        if module.name not in FRAMEWORK:
            yield importlib.import_module(f"{__name__}.{module.name}")


def _plugins() -> Iterator[tuple[str, tuple[Task, ...]]]:
    """(who, tasks) of each module that other distributions name (:data:`ENTRY_POINTS`); one whose
    ``TASKS`` is not a tuple of tasks is warned of and left out (:mod:`besman.core.plugins`)."""
    for who, module in plugin_modules(ENTRY_POINTS, "task"):
        entries = tuple(getattr(module, "TASKS", ()))
        wrong = [
            e for e in entries if not (isinstance(e, Task) and isinstance(getattr(e, "name", None), str))
        ]
        if wrong:
            warn_plugin(
                f"{who} is left out: {module.__name__}.TASKS holds {wrong[0]!r}, which is not a named besman "
                "task"
            )
            continue
        yield who, entries


def _registered() -> dict[str, Task]:
    found: dict[str, Task] = {}
    for module in _builtin():
        for entry in getattr(module, "TASKS", ()):
            for name in (entry.name, *entry.aliases):
                if name in found:
                    raise RuntimeError(f"two tasks are called {name!r}: {found[name]!r} and {entry!r}")
                found[name] = entry
    for who, entries in _plugins():
        for entry in entries:
            names = (entry.name, *entry.aliases)
            taken = next((name for name in names if name in found), None)
            if taken is not None:  # what is registered first (besman's own tasks) keeps its name
                owner = type(found[taken]).__module__
                warn_plugin(
                    f"{who}: its task {taken!r} is left out: {owner} already has a task called {taken!r}"
                )
                continue
            found.update(dict.fromkeys(names, entry))
    return found


_BY_NAME = _registered()
_FIRST = type(_BY_NAME[DEFAULT]).__module__
# The default task's module first (the default task, then its module's others), then the other modules'.
TASKS: dict[str, Task] = {
    name: entry
    for name, entry in sorted(_BY_NAME.items(), key=lambda item: type(item[1]).__module__ != _FIRST)
    if name == entry.name
}


def task_names() -> list[str]:
    """Every name a tree file's ``task`` may have: the tasks' names and their aliases."""
    return list(_BY_NAME)


def task(name: str) -> Task:
    """The registry's task ``name`` (or one of its aliases); an unknown name lists the tasks."""
    if name not in _BY_NAME:
        raise UnknownNameError(f"unknown task {name!r}; tasks: {', '.join(TASKS)}")
    return _BY_NAME[name]
