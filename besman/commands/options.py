"""Numeric option values with their ranges, checked by the parser.

An option's ``type`` converts its text and checks its range in one step, so that a value out of range is
refused by argparse - with the option's name, the range and the value, before the command does anything -
instead of being taken for "not given" (a seed count of 0) or failing deep inside a run (a port of 70000).
Finer limits that belong to a domain (K >= 2 training tasks) stay with the settings that hold them.
"""

from __future__ import annotations

import argparse
import math
from collections.abc import Callable


def integer(low: int, high: int | None = None) -> Callable[[str], int]:
    """An integer in [low, high] (no upper bound if ``high`` is None)."""
    described = f"an integer from {low} to {high}" if high is not None else f"an integer >= {low}"

    def convert(text: str) -> int:
        try:
            value = int(text)
        except ValueError:
            raise argparse.ArgumentTypeError(f"must be {described}, got {text!r}") from None
        if value < low or (high is not None and value > high):
            raise argparse.ArgumentTypeError(f"must be {described}, got {value}")
        return value

    return convert


def positive(text: str) -> float:
    """A finite number above 0."""
    try:
        value = float(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"must be a number above 0, got {text!r}") from None
    if not (math.isfinite(value) and value > 0):
        raise argparse.ArgumentTypeError(f"must be a number above 0, got {text}")
    return value


COUNT = integer(1)  # how many of something
MAX_SEED = 2**32 - 1  # what numpy's and CMA-ES's generators accept
SEED = integer(0, MAX_SEED)
PORT = integer(0, 65535)  # a TCP port to listen on (0: any free one)
