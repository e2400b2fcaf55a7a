import os
from pathlib import Path

import pytest

# Offscreen rendering on machines without a screen; must precede the first `import mujoco`.
os.environ.setdefault("MUJOCO_GL", "egl")

SHARED_RECORDINGS = Path(__file__).resolve().parents[2] / "shared" / "data" / "dfki_pick_and_place"

# The files that take minutes, longest first: the suite's workers take whole files in order (--dist
# loadfile), and a long file started last would leave one worker running alone at the end.
LONG_FIRST = (
    "test_learning_pipeline.py",
    "test_learning_full.py",
    "test_gallery.py",
    "test_install.py",
    "test_benchmarks.py",
    "test_throwing_experiment.py",
    "test_learning_from_datasets.py",
    "test_datasets.py",
    "test_hardening.py",
    "test_widowx_pair.py",
    "test_widowx.py",
    "test_ur5e.py",
)


def pytest_collection_modifyitems(items) -> None:
    rank = {name: index for index, name in enumerate(LONG_FIRST)}
    items.sort(key=lambda item: rank.get(item.path.name, len(LONG_FIRST)))  # stable: file order kept


@pytest.fixture
def shared_recordings() -> Path:
    """The DFKI pick-and-place recordings beside the repository (``../shared``); skips without them."""
    if not SHARED_RECORDINGS.exists():
        pytest.skip("the shared recordings sit beside the repository (../shared)")
    return SHARED_RECORDINGS


@pytest.fixture(autouse=True)
def _in_a_temporary_directory(tmp_path, monkeypatch):
    """Every test runs in its own temporary folder: MuJoCo writes MUJOCO_LOG.TXT into the working directory
    on a warning (tests provoke faults on purpose), and nothing a test writes may land in the checkout."""
    monkeypatch.chdir(tmp_path)
