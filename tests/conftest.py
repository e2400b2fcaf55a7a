import collections
import json
import os
from pathlib import Path

import pytest

# Offscreen rendering on machines without a screen; must precede the first `import mujoco`.
os.environ.setdefault("MUJOCO_GL", "egl")

SHARED_RECORDINGS = Path(__file__).resolve().parents[2] / "shared" / "data" / "dfki_pick_and_place"

# Each test file's time in the last full run (setup, call and teardown of its tests, s), kept by
# ``pytest -m "" --record-durations`` (the README's test command, so every CI run and every full local run
# keeps them; a run updates the files it ran and keeps the others'): the suite's workers take whole files in
# order (--dist loadfile), longest first, so that no long file starts last and leaves one worker running
# alone at the end. A file not listed yet runs after those listed.
DURATIONS = Path(__file__).with_name("durations.json")


def pytest_addoption(parser) -> None:
    parser.addoption(
        "--record-durations",
        action="store_true",
        help=f"write each test file's time to {DURATIONS.name} (after a full run: -m '')",
    )


def pytest_collection_modifyitems(items) -> None:
    seconds = json.loads(DURATIONS.read_text())["seconds"] if DURATIONS.is_file() else {}
    items.sort(key=lambda item: -seconds.get(item.path.name, 0.0))  # stable: file order kept


_spent: collections.Counter = collections.Counter()


def pytest_runtest_logreport(report) -> None:
    _spent[Path(report.nodeid.split("::")[0]).name] += report.duration  # on xdist's controller too


def pytest_sessionfinish(session) -> None:
    recording = session.config.getoption("--record-durations")
    if recording and not hasattr(session.config, "workerinput"):  # the controller (or a run without xdist)
        kept = json.loads(DURATIONS.read_text())["seconds"] if DURATIONS.is_file() else {}
        kept.update({name: round(total, 1) for name, total in _spent.items()})
        kept = {name: kept[name] for name in kept if (Path(__file__).parent / name).is_file()}  # files gone
        seconds = dict(sorted(kept.items(), key=lambda item: -item[1]))
        DURATIONS.write_text(json.dumps({"schema_version": 1, "seconds": seconds}, indent=1) + "\n")


@pytest.fixture(autouse=True)
def mujoco_warnings(request):
    """MuJoCo's warnings while the test runs ("simulation is unstable", ...), in this process: any fails the
    test unless it is marked ``mujoco_warnings`` (it provokes them); a test may also read the list."""
    import mujoco

    said: list[str] = []
    mujoco.set_mju_user_warning(said.append)
    yield said
    mujoco.set_mju_user_warning(None)
    if said and request.node.get_closest_marker("mujoco_warnings") is None:
        pytest.fail(f"MuJoCo warned {len(said)} times: {said[0].strip()}", pytrace=False)


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
