"""Figures as files: matplotlib without a display, PNGs written atomically.

Importing this module selects matplotlib's file-only backend (Agg) before pyplot loads, so plots work on
headless machines; :func:`save_png` renders a figure and writes it whole (temporary file, then rename).
"""

from __future__ import annotations

import io
from pathlib import Path

import matplotlib

matplotlib.use("Agg")  # files only, no display
import matplotlib.pyplot as plt

from besman.core.storage import write_atomically


def save_png(figure: plt.Figure, path: str | Path, dpi: int = 100) -> Path:
    """Writes ``figure`` to ``path`` as a PNG and closes it."""
    buffer = io.BytesIO()
    figure.savefig(buffer, format="png", dpi=dpi)
    plt.close(figure)
    return write_atomically(path, buffer.getvalue())
