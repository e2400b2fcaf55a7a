"""The layout is the architecture: imports point one way (the command line, tasks, trees, learning, sim,
robots; each may use those below it), and ``skills`` imports nothing else of ours. Every import counts,
those inside functions too: a deferred import is still a dependency."""

import ast
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
# Top to bottom; ``besman`` is the command line (besman/), ``examples`` the shipped data every layer reads.
LAYERS = ("besman", "tasks", "trees", "learning", "sim", "robots", "skills")


def imported(path: Path) -> set[str]:
    """The besman subpackages a module imports (``besman.X...`` or ``from besman import X``)."""
    found = set()
    for node in ast.walk(ast.parse(path.read_text())):
        if isinstance(node, ast.ImportFrom) and node.module == "besman":
            found |= {alias.name for alias in node.names}
        elif isinstance(node, ast.ImportFrom) and node.module and node.module.startswith("besman."):
            found.add(node.module.split(".")[1])
        elif isinstance(node, ast.Import):
            found |= {a.name.split(".")[1] for a in node.names if a.name.startswith("besman.")}
    return {name if name in LAYERS or name == "examples" else "besman" for name in found}


def test_every_import_points_down_and_skills_imports_only_skills():
    upward = []
    for rank, layer in enumerate(LAYERS):
        for path in sorted((ROOT / layer).rglob("*.py")):
            above = {name for name in imported(path) if name in LAYERS[:rank]}
            if layer == "skills":
                above = imported(path) - {"skills"}
            upward += [f"{path.relative_to(ROOT)} imports besman.{name}" for name in sorted(above)]
    assert upward == []
