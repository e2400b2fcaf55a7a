"""The layout is the architecture: imports point one way (the command line and its experiments, tasks, trees,
learning, datasets, sim, robots; each may use those below it), ``skills`` imports only ``core``, ``core``
nothing else of ours, and no module imports itself through others (no import circle). Every import counts,
those inside functions and for type annotations too: a deferred import is still a dependency."""

import ast
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]
# Top to bottom; ``besman`` is the command line (besman/, with besman.experiments), ``examples`` the shipped
# data every layer reads.
LAYERS = ("besman", "tasks", "trees", "learning", "datasets", "sim", "robots", "skills", "core")
FOLDERS = {
    **{layer: f"besman.{layer}" for layer in LAYERS[1:]},
    "besman": "besman",
    "examples": "besman.examples",
}


def modules() -> dict[str, Path]:
    """Every module of the distribution by its dotted name (a package by its ``__init__.py``)."""
    found = {}
    for folder, package in FOLDERS.items():
        for path in (ROOT / folder).rglob("*.py"):
            parts = path.relative_to(ROOT / folder).with_suffix("").parts
            found[".".join((package, *parts[: -1 if parts[-1] == "__init__" else None]))] = path
    return found


def imports(path: Path) -> set[str]:
    """The besman names a module imports: ``besman.X.Y`` of ``import`` and ``from besman.X import Y``."""
    found = set()
    for node in ast.walk(ast.parse(path.read_text())):
        if isinstance(node, ast.ImportFrom) and node.level == 0 and (node.module or "").startswith("besman"):
            found |= {f"{node.module}.{alias.name}" for alias in node.names}
        elif isinstance(node, ast.Import):
            found |= {alias.name for alias in node.names if alias.name.startswith("besman")}
    return found


def layer(name: str) -> str:
    part = name.split(".")[1] if "." in name else "besman"
    return part if part in LAYERS or part == "examples" else "besman"


def test_every_import_points_down_and_skills_and_core_stay_below():
    upward = []
    for name, path in modules().items():
        own = layer(name)
        if own == "examples":
            continue
        rank = LAYERS.index(own)
        allowed = {"skills": {"skills", "core"}, "core": {"core"}}.get(own)
        for target in sorted({layer(t) for t in imports(path)}):
            wrong = target not in allowed if allowed else target in LAYERS[:rank]
            if wrong:
                upward.append(f"{path.relative_to(ROOT)} imports besman.{target}")
    assert upward == []


def import_graph() -> dict[str, set[str]]:
    """Each module and the modules it imports (a name imported from a package is its module if it is one,
    else the package)."""
    known = modules()

    def module_of(name: str) -> str | None:
        while name not in known and "." in name:
            name = name.rsplit(".", 1)[0]
        return name if name in known else None

    return {
        name: {m for m in map(module_of, imports(path)) if m is not None} - {name}
        for name, path in known.items()
    }


def circles(graph: dict[str, set[str]]) -> list[list[str]]:
    """The strongly connected components of more than one module (Tarjan, iterative)."""
    index, low, on_stack, stack, found, counter = {}, {}, set(), [], [], 0
    for root in graph:
        if root in index:
            continue
        work = [(root, iter(sorted(graph[root])))]
        index[root] = low[root] = counter
        counter += 1
        stack.append(root)
        on_stack.add(root)
        while work:
            node, children = work[-1]
            child = next(children, None)
            if child is not None:
                if child not in index:
                    index[child] = low[child] = counter
                    counter += 1
                    stack.append(child)
                    on_stack.add(child)
                    work.append((child, iter(sorted(graph[child]))))
                elif child in on_stack:
                    low[node] = min(low[node], index[child])
                continue
            work.pop()
            if work:
                low[work[-1][0]] = min(low[work[-1][0]], low[node])
            if low[node] == index[node]:
                component = []
                while True:
                    member = stack.pop()
                    on_stack.discard(member)
                    component.append(member)
                    if member == node:
                        break
                if len(component) > 1:
                    found.append(sorted(component))
    return found


def test_no_module_imports_itself_through_others():
    assert circles(import_graph()) == []


@pytest.mark.parametrize(
    ("graph", "expected"),
    [
        ({"a": {"b"}, "b": {"c"}, "c": {"a"}, "d": {"a"}}, [["a", "b", "c"]]),
        ({"a": {"b"}, "b": set()}, []),
    ],
)
def test_the_circle_search_finds_a_circle_of_three(graph, expected):
    assert circles(graph) == expected


def test_no_throwing_name_below_the_tasks():
    """Throwing is one task: its modules live in its package, and the generic packages do not know it."""
    named = [
        f"{path.relative_to(ROOT)} imports {target}"
        for name, path in modules().items()
        if layer(name) in ("trees", "learning", "datasets", "sim", "robots", "skills", "core")
        for target in imports(path)
        if "throw" in target
    ]
    named += [
        str(p.relative_to(ROOT)) for f in ("sim", "trees", "learning") for p in (ROOT / f).rglob("*throw*.py")
    ]
    assert named == []


def test_the_concepts_page_lists_the_tasks_in_the_registrys_order():
    from besman.tasks import TASKS

    page = (ROOT / "docs" / "concepts.md").read_text()
    assert f"list(TASKS)\n# {list(TASKS)}\n" in page
