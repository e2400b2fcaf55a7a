import os
from pathlib import Path

import pytest

# Offscreen rendering on machines without a screen; must precede the first `import mujoco`.
os.environ.setdefault("MUJOCO_GL", "egl")

SHARED_RECORDINGS = Path(__file__).resolve().parents[2] / "shared" / "data" / "dfki_pick_and_place"


@pytest.fixture
def shared_recordings() -> Path:
    """The DFKI pick-and-place recordings beside the repository (``../shared``); skips without them."""
    if not SHARED_RECORDINGS.exists():
        pytest.skip("the shared recordings sit beside the repository (../shared)")
    return SHARED_RECORDINGS
