"""The previous release's names keep working for this one, with a warning that names the new one: modules that
moved (the same module object under both names), names that left a module or were renamed, and command-line
spellings."""

import importlib
import subprocess
import sys
import warnings
from pathlib import Path

import pytest
from helpers import run_cli

from besman.cli import OLD_SPELLINGS, respelled
from besman.core.moved import MOVED, MOVED_NAMES

ROOT = Path(__file__).resolve().parents[1]
MOVED_PAIRS = [
    (module, old, new)
    for module, names in sorted(MOVED_NAMES.items())
    for old, new in sorted(names.items())
    if old != "*"  # a module that became a package: below
]


def test_every_moved_module_is_the_same_module_under_its_old_name_with_a_warning():
    """In a fresh interpreter (this one may have imported old names already, without a warning): each old
    name warns once, naming the new one, and is the very module object, which keeps its own name."""
    script = (
        "import importlib, warnings\n"
        "from besman.core.moved import MOVED\n"
        "for old, new in sorted(MOVED.items()):\n"
        "    module = importlib.import_module(new)\n"
        "    with warnings.catch_warnings(record=True) as caught:\n"
        "        warnings.simplefilter('always')\n"
        "        same = importlib.import_module(old) is module\n"
        "    print(old, same, module.__spec__.name, '|'.join(str(w.message) for w in caught))\n"
    )
    out = subprocess.run([sys.executable, "-c", script], capture_output=True, text=True, check=True).stdout
    assert out.splitlines() == [f"{old} True {new} {old} is now {new}" for old, new in sorted(MOVED.items())]


def test_the_moved_modules_are_imported_in_one_interpreter_as_the_same_objects():
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", DeprecationWarning)
        for old, new in MOVED.items():
            assert importlib.import_module(old) is importlib.import_module(new)
    from besman.core.errors import InputError
    from besman.skills.errors import InputError as OldInputError

    assert OldInputError is InputError


@pytest.mark.parametrize(("module", "old", "new"), MOVED_PAIRS)
def test_a_moved_or_renamed_name_gives_the_new_object_with_a_warning(module, old, new):
    home, name = new.split(":")
    with pytest.warns(DeprecationWarning, match=f"{module}.{old} is now {home}.{name}"):
        value = getattr(importlib.import_module(module), old)
    assert value is getattr(importlib.import_module(home), name)


@pytest.mark.parametrize(
    ("package", "name", "home"),
    [
        ("besman.learning.pipeline", "learn", "besman.learning.pipeline.end_to_end"),
        ("besman.learning.pipeline", "LearnSettings", "besman.learning.pipeline.end_to_end"),
        ("besman.learning.segmentation", "segment", "besman.learning.segmentation.segmenter"),
    ],
)
def test_a_module_that_became_a_package_still_gives_its_names(package, name, home):
    with pytest.warns(DeprecationWarning, match=f"{package}.{name} is now {home}.{name}"):
        value = getattr(importlib.import_module(package), name)
    assert value is getattr(importlib.import_module(home), name)


def test_an_unknown_name_is_still_an_attribute_error():
    import besman.sim.world as world

    with pytest.raises(AttributeError, match="has no attribute 'nothing'"):
        world.nothing  # noqa: B018


@pytest.mark.parametrize(
    ("argv", "expected"),
    [
        (["demos", "show", "x.tsv"], ["recordings", "show", "x.tsv"]),
        (["learn", "--demos", "d", "--tasks", "2"], ["learn", "--demos", "d", "--training-tasks", "2"]),
        (["learn", "--tasks=2"], ["learn", "--training-tasks=2"]),
        (["run", "--tasks", "2"], ["run", "--tasks", "2"]),  # only learn's --tasks was renamed
        (["learn", "--demos", "demos"], ["learn", "--demos", "demos"]),  # a value is no command
        (["--version"], ["--version"]),
    ],
)
def test_old_spellings_are_respelled_and_nothing_else(argv, expected, capsys):
    assert respelled(argv) == expected
    warned = capsys.readouterr().err.splitlines()
    assert len(warned) == (argv != expected)
    assert all(line.startswith("besman: warning: besman ") for line in warned)


def test_the_old_recordings_command_runs_with_one_warning_line(capsys):
    code, out, err = run_cli(capsys, "demos", "show", str(ROOT / "examples" / "data" / "subject1_run1.tsv"))
    assert code == 0 and "738 samples" in out
    assert (
        err == "besman: warning: besman demos is now recordings (the old spelling goes in the next release)\n"
    )
    assert set(OLD_SPELLINGS.values()) == {"recordings", "--training-tasks"}
