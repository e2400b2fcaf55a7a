"""The documentation's "Add a node type" page (docs/node-types.md), followed literally; and the rules of
registering node types, in code and from installed plugins."""

import subprocess
import sys
from pathlib import Path
from typing import ClassVar

import pytest
from helpers import follow_page, install_plugin
from py_trees.common import Status

from besman.core.errors import InputError
from besman.trees.base import RoleBehaviour
from besman.trees.nodes import NODE_TYPES, register_node_type

ROOT = Path(__file__).resolve().parents[1]
PAGE = ROOT / "docs" / "node-types.md"


@pytest.mark.slow
def test_the_add_a_node_type_page_works_as_written(tmp_path):
    described, checked, ran, tested = follow_page(PAGE, tmp_path / "besman-hand-checks")
    said = "HandAbove: Succeeds while the hand's tool frame is higher than z (m, in the world)"
    assert described.startswith(said)
    assert "  z: float, required\n" in described
    assert checked.strip().endswith("lifted.yaml: ok")
    assert ran.startswith("SUCCESS: placement error")
    assert "2 passed" in tested


class Counted(RoleBehaviour):
    """Succeeds on its ``times``-th tick."""

    parameters: ClassVar = {"times": "int>=1"}

    def __init__(self, name: str, *, times: int = 1) -> None:
        super().__init__(name)
        self.times, self.ticks = times, 0

    def update(self) -> Status:
        self.ticks += 1
        return Status.SUCCESS if self.ticks >= self.times else Status.RUNNING


def test_a_registered_leaf_is_loaded_checked_and_described_like_besmans_own(tmp_path):
    from besman.trees import TreeFileError, load_tree
    from besman.trees.reference import node_reference, tree_schema

    assert register_node_type(Counted) == "Counted"
    try:
        assert node_reference("Counted")["Counted"]["parameters"]["times"]["range"] == ">= 1"
        assert "Counted" in str(tree_schema())
        tree = tmp_path / "counted.yaml"
        tree.write_text("besman_tree: 1\nroot:\n  Counted: {name: three, times: 3}\n")
        assert load_tree(tree).times == 3
        tree.write_text("besman_tree: 1\nroot:\n  Counted: {name: none, times: 0}\n")
        with pytest.raises(TreeFileError, match=r"counted\.yaml:3: .*times.* at least 1"):
            load_tree(tree)
        with pytest.raises(InputError, match="the node type 'Counted' exists already"):
            register_node_type(Counted)
    finally:
        del NODE_TYPES["Counted"]


def test_what_cannot_be_a_node_type_is_refused_by_name():
    class Wait(RoleBehaviour):  # besman's own name
        pass

    class Misdeclared(RoleBehaviour):
        parameters: ClassVar = {"height": "float"}

        def __init__(self, name: str) -> None:
            super().__init__(name)

    class Unkind(RoleBehaviour):
        parameters: ClassVar = {"height": "metres"}

        def __init__(self, name: str, *, height: float = 1.0) -> None:
            super().__init__(name)

    for node, message in [
        (Wait, r"the node type 'Wait' exists already \(besman\.trees\.timing\.Wait\)"),
        (Misdeclared, r"Misdeclared: declares the parameter 'height', which it does not take"),
        (Unkind, r"Unkind: parameter 'height' is of kind 'metres'; the kinds: str, float"),
        (print, r"a node type is a leaf class"),
    ]:
        with pytest.raises(InputError, match=message):
            register_node_type(node)
    assert NODE_TYPES["Wait"].build.__module__ == "besman.trees.timing"


# Installed node-type plugins (tests/helpers.py: install_plugin): distribution -> (module, its source).
BROKEN_PLUGINS = {
    "besman-missing": ("missing_dependency", "import not_installed_anywhere\n"),
    "besman-clash": (
        "clashing_node",
        "from typing import ClassVar\n"
        "from besman.trees.base import RoleBehaviour\n\n"
        "class Wait(RoleBehaviour):\n"
        "    parameters: ClassVar = {}\n\n"
        "NODE_TYPES = (Wait, print)\n",
    ),
}


def test_a_broken_node_type_plugin_is_one_warning_line_and_trees_still_work(tmp_path):
    site = tmp_path / "site"
    for dist, (module, source) in BROKEN_PLUGINS.items():
        install_plugin(site, dist, "besman.node_types", module)
        (site / f"{module}.py").write_text(source)
    result = subprocess.run(
        [
            Path(sys.executable).parent / "besman",
            "tree",
            "check",
            ROOT / "examples/trees/grasp_then_place.yaml",
        ],
        capture_output=True,
        text=True,
        env={"PYTHONPATH": str(site), "PATH": "/usr/bin:/bin"},
    )
    assert result.returncode == 0 and result.stdout.strip().endswith("grasp_then_place.yaml: ok")
    warnings = sorted(result.stderr.splitlines())  # the plugins in the order they are found
    assert len(warnings) == 3, result.stderr
    assert warnings[0].startswith(
        "besman: warning: the node-type plugin 'clashing_node' of the distribution besman-clash 1.0: "
        "<built-in function print>: a node type is a leaf class"
    )
    assert "besman-clash 1.0: clashing_node.Wait: the node type 'Wait' exists already" in warnings[1]
    assert warnings[2].startswith(
        "besman: warning: the node-type plugin 'missing_dependency' of the distribution besman-missing 1.0 "
        "is left out: loading missing_dependency raised ModuleNotFoundError"
    )
