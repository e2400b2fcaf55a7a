"""A tree file's MODULE:NAME templates and pools: registered or in an allowed module, never imported because
the file names them, and never imported by a check."""

import json
import os
import subprocess
import sys
import textwrap
from pathlib import Path

import pytest
from helpers import run_cli

from besman.core.errors import InputError
from besman.trees import TreeFileError, check_tree, load_tree, register_pool, register_template, registry

MODULE = "besman_test_recorder"  # a module that leaves a marker beside itself when it is imported
TREE = """besman_tree: 1
task: pick-place
root:
  Sequence:
    name: both
    children:
      - InstantiateSkillTemplate:
          name: from pool
          pool: "MODULE:POOL"
          template_name: reach
          remap: {tau: /task/tau}
      - InstantiateSkillTemplate:
          name: direct
          template: "MODULE:REACH"
          namespace: direct
          remap: {tau: /task/tau}
""".replace("MODULE", MODULE)


@pytest.fixture
def folder(tmp_path, monkeypatch):
    """A folder with the recording module (importable) and a tree that names it; the module is forgotten
    after the test."""
    (tmp_path / f"{MODULE}.py").write_text(
        textwrap.dedent("""
        import pathlib

        pathlib.Path(__file__).with_name("imported.marker").write_text("imported")

        from besman.skills import DMP, MovementPrimitive


        class Reach:
            def instantiate(self, tau):
                return MovementPrimitive(DMP(8, goal=0.1 * float(tau[0])), "reach")


        REACH = Reach()
        POOL = {"reach": REACH}
        NOT_A_POOL = REACH
        """)
    )
    (tmp_path / "skills.yaml").write_text(TREE)
    monkeypatch.syspath_prepend(str(tmp_path))
    monkeypatch.delitem(sys.modules, MODULE, raising=False)
    yield tmp_path
    sys.modules.pop(MODULE, None)


def never_imported(folder: Path) -> bool:
    return not (folder / "imported.marker").exists() and MODULE not in sys.modules


def test_tree_check_on_the_command_line_never_imports_the_module(folder):
    environment = os.environ | {"PYTHONPATH": str(folder)}  # importable, were anything to import it
    check = [sys.executable, "-m", "besman", "tree", "check", str(folder / "skills.yaml")]
    allow = ["--allow-module", MODULE]
    allowed = subprocess.run([*check, *allow], capture_output=True, text=True, env=environment)
    assert allowed.returncode == 0, allowed.stderr
    later = f"{MODULE}:POOL, {MODULE}:REACH: allowed, imported when the tree runs"
    assert allowed.stdout == f"{folder / 'skills.yaml'}: ok ({later})\n"
    refused = subprocess.run(check, capture_output=True, text=True, env=environment)
    assert refused.returncode == 1 and refused.stderr == ""
    assert f"--allow-module {MODULE}" in refused.stdout and len(refused.stdout.splitlines()) == 1
    assert never_imported(folder)


def test_the_python_check_never_imports_the_module(folder, capsys):
    assert check_tree(folder / "skills.yaml", allow_modules=[MODULE]) == [f"{MODULE}:POOL", f"{MODULE}:REACH"]
    code, out, _ = run_cli(capsys, "tree", "check", str(folder / "skills.yaml"), "--allow-module", MODULE)
    assert code == 0 and "imported when the tree runs" in out
    refused = rf"skills.yaml:9: root.*pool: '{MODULE}:POOL': module '{MODULE}' is not allowed"
    with pytest.raises(TreeFileError, match=refused):
        check_tree(folder / "skills.yaml")
    assert never_imported(folder)


def test_a_check_still_checks_the_leaves_other_parameters(folder):
    (folder / "no_name.yaml").write_text(TREE.replace("template_name: reach", "namespace: pool"))
    with pytest.raises(TreeFileError, match=r"no_name.yaml:\d+: .*a pool needs a template_name"):
        check_tree(folder / "no_name.yaml", allow_modules=[MODULE])
    assert never_imported(folder)


def test_a_module_not_allowed_is_refused_with_how_to_allow_it(folder):
    with pytest.raises(TreeFileError) as refused:
        load_tree(folder / "skills.yaml")
    message = str(refused.value)
    assert message.startswith(f"{folder / 'skills.yaml'}:9: root.Sequence.children[0]")
    assert f"--allow-module {MODULE}" in message and f"allow_modules=['{MODULE}']" in message
    assert "register_pool" in message
    assert never_imported(folder)


@pytest.mark.parametrize(
    "reference", ["..x:y", "x", "x:", ":y", "x:y:z", "a b:c", "x.:y", "x:y.z", "import:x", "../pools/x"]
)
def test_text_that_is_no_reference_gives_one_line(folder, capsys, reference):
    path = folder / "bad.yaml"
    path.write_text(
        f'besman_tree: 1\nroot:\n  InstantiateSkillTemplate: {{name: t, template: "{reference}"}}\n'
    )
    where = r"bad.yaml:3: root.InstantiateSkillTemplate.template: "
    with pytest.raises(TreeFileError, match=where + ".* is not a reference MODULE:NAME"):
        check_tree(path, allow_modules=["x", "a"])
    code, out, err = run_cli(capsys, "tree", "check", str(path))
    assert code == 1 and err == "" and len(out.splitlines()) == 1 and "MODULE:NAME" in out


def test_an_allowed_module_is_imported_when_the_tree_is_built_and_works(folder, capsys):
    root = load_tree(folder / "skills.yaml", allow_modules=[MODULE])
    assert (folder / "imported.marker").exists() and MODULE in sys.modules
    assert root.children[0].pool["reach"] is root.children[1].template
    assert root.children[1].template.instantiate([2.0]).name == "reach"
    code, out, _ = run_cli(capsys, "tree", "show", str(folder / "skills.yaml"), "--allow-module", MODULE)
    assert code == 0 and "from pool" in out


def test_besman_run_imports_an_allowed_module_and_runs_the_tree(folder, capsys):
    run = ["run", str(folder / "skills.yaml"), "--json", "--set", "tau=1.5"]
    code, _, err = run_cli(capsys, *run)
    assert code == 2 and f"--allow-module {MODULE}" in err and never_imported(folder)
    code, out, _ = run_cli(capsys, *run, "--allow-module", MODULE)
    summary = json.loads(out)  # the tree ran; it moves no box, so pick and place is not done: exit 1
    assert code == 1 and summary["status"] == "SUCCESS" and not summary["success"], summary
    assert summary["tree"] == str((folder / "skills.yaml").resolve())


def test_a_registered_template_or_pool_needs_no_module(folder, monkeypatch):
    monkeypatch.setattr(registry, "_TEMPLATES", {})
    monkeypatch.setattr(registry, "_POOLS", {})

    class Reach:
        def instantiate(self, tau):
            raise AssertionError("not instantiated by loading")

    reach = Reach()
    register_template(f"{MODULE}:REACH", reach)
    register_pool(f"{MODULE}:POOL", {"reach": reach})
    assert check_tree(folder / "skills.yaml") == []  # registered: checked whole, nothing left to import
    root = load_tree(folder / "skills.yaml")
    assert root.children[1].template is reach and root.children[0].pool["reach"] is reach
    assert never_imported(folder)
    with pytest.raises(InputError, match="is not a reference MODULE:NAME"):
        register_template("..x:y", reach)
    with pytest.raises(InputError, match="has no instantiate"):
        register_template("lab:reach", object())
    with pytest.raises(InputError, match="is not a pool"):
        register_pool("lab:pool", reach)


def test_an_allowed_attribute_of_the_wrong_kind_or_missing_is_refused(folder):
    (folder / "wrong.yaml").write_text(TREE.replace(":POOL", ":NOT_A_POOL").replace(":REACH", ":NOTHING"))
    with pytest.raises(TreeFileError, match=rf"'{MODULE}:NOT_A_POOL' is not a pool"):
        load_tree(folder / "wrong.yaml", allow_modules=[MODULE])
    (folder / "missing.yaml").write_text(TREE.replace(":REACH", ":NOTHING"))
    with pytest.raises(TreeFileError, match=rf"module '{MODULE}' has no 'NOTHING'"):
        load_tree(folder / "missing.yaml", allow_modules=[MODULE])


@pytest.mark.parametrize("allowed", ["my_skills", ["a-b"], [""], [3]])
def test_an_allow_list_holds_module_names(allowed):
    with pytest.raises(InputError, match="allow_modules"):
        check_tree(Path(__file__).parents[1] / "examples" / "trees" / "grasp.yaml", allow_modules=allowed)


def test_a_malformed_allow_module_option_gives_one_line(capsys):
    code, out, err = run_cli(capsys, "tree", "check", "nothing.yaml", "--allow-module", "../x")
    assert code == 2 and out == "" and err.count("\n") == 1 and "'../x' is not a module name" in err
