"""The versions besman admits: a floor never lets in a release known to be unsafe with untrusted input."""

import tomllib
from pathlib import Path

from packaging.requirements import Requirement

PYPROJECT = Path(__file__).resolve().parents[1] / "pyproject.toml"

# Releases that harm a user who opens a stranger's file with them, and why.
UNSAFE = {
    # Reading a Parquet file unpickles its extension metadata (CVE-2023-47248; fixed in 14.0.1), and
    # datasets are downloaded from strangers.
    "pyarrow": ["0.14.0", "13.0.0", "14.0.0"],
}


def test_no_dependency_admits_a_release_that_unpickles_or_otherwise_trusts_a_strangers_file():
    project = tomllib.loads(PYPROJECT.read_text())["project"]
    declared = [
        *project["dependencies"],
        *(r for extra in project["optional-dependencies"].values() for r in extra),
    ]
    requirements = [Requirement(text) for text in declared]
    for name, releases in UNSAFE.items():
        found = [r for r in requirements if r.name == name]
        assert found, f"{name} is no longer declared: update UNSAFE"
        for requirement in found:
            admitted = [v for v in releases if requirement.specifier.contains(v, prereleases=True)]
            assert not admitted, f"{requirement} admits {admitted}"
