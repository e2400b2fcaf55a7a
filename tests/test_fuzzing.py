"""Property-based fuzzing of the loaders of user files: any bytes give a result or the project's own error
(:class:`~besman.core.errors.BesmanError`), never another exception, a hang or unbounded memory."""

import contextlib

import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from besman.core.errors import BesmanError
from besman.learning import load
from besman.trees import load_tree

# Derandomised (same examples every run, no database in the checkout); a few seconds in all.
FUZZ = settings(
    max_examples=300,
    deadline=2000,
    derandomize=True,
    database=None,
    suppress_health_check=[HealthCheck.function_scoped_fixture],
)

TREE_WORDS = [
    "besman_tree: 1\n",
    "root:\n",
    "  Sequence:\n",
    "    name: s\n",
    "    children:\n",
    "      - Wait: {name: w, duration: 0}\n",
    "  Wait: {name: w, duration: 1}\n",
    "  include: other.yaml\n",
    "remap: {a: b}\n",
    "&a [1]\n",
    "*a\n",
    "- ",
    "{",
    "}",
    "[",
    "]",
    ": ",
    "\t",
    "  ",
    "\n",
    "Retry: {name: r, attempts: 2, child: {Wait: {name: w, duration: 0}}}\n",
    "timeout: -1\n",
    "x",
]
TSV_HEADER = "Frame\tTime\tHand top X\tHand top Y\tHand top Z\n"


def tree_texts():
    return st.one_of(
        st.binary(max_size=400),
        st.lists(st.sampled_from(TREE_WORDS), max_size=30).map(lambda words: "".join(words).encode()),
    )


@FUZZ
@given(data=tree_texts())
def test_any_tree_file_loads_or_gives_a_tree_file_error(tmp_path, data):
    path = tmp_path / "fuzz.yaml"
    path.write_bytes(data)
    with contextlib.suppress(BesmanError):
        load_tree(path)


def recording_texts():
    cell = st.one_of(
        st.floats(allow_nan=True, allow_infinity=True).map(repr),
        st.integers(-(10**12), 10**12).map(str),
        st.sampled_from(["", "null", "NaN", "x", "1e308", "-0"]),
    )
    row = st.lists(cell, min_size=3, max_size=6).map("\t".join)
    # Plausible clocks with arbitrary coordinates reach the checks behind the parsing.
    clocked = st.lists(st.tuples(cell, cell, cell), min_size=2, max_size=12).map(
        lambda rows: "\n".join(f"{i + 1}\t{0.01 * i:.3f}\t{x}\t{y}\t{z}" for i, (x, y, z) in enumerate(rows))
    )
    return st.one_of(
        st.binary(max_size=400),
        st.lists(row, max_size=12).map(lambda rows: (TSV_HEADER + "\n".join(rows)).encode()),
        clocked.map(lambda rows: (TSV_HEADER + rows).encode()),
    )


@FUZZ
@given(data=recording_texts())
def test_any_recording_loads_or_gives_a_demonstration_error(tmp_path, data):
    for suffix in (".tsv", ".csv"):
        path = tmp_path / f"fuzz{suffix}"
        path.write_bytes(data if suffix == ".tsv" else data.replace(b"\t", b","))
        try:
            demo = load(path)
        except BesmanError:
            continue
        assert len(demo.times) >= 2


@FUZZ
@given(data=st.binary(max_size=600))
def test_any_npz_loads_or_gives_a_demonstration_error(tmp_path, data):
    path = tmp_path / "fuzz.npz"
    path.write_bytes(data)
    with pytest.raises(BesmanError):
        load(path)
