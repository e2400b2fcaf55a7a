"""Seeds handed on: what a seeded computation gives its parts, and what pycma is given.

A seed (0 .. 2**32 - 1: what numpy's legacy generator, scikit-learn and pycma accept, and what the command
line takes) often seeds several generators: one per task, per coordinate, per search. Arithmetic on it
(``seed + j``) leaves that range at its top and lets two seeds' children coincide; :func:`child_seed`
hashes the seed and the child's keys with numpy's ``SeedSequence`` into the range instead.
"""

from __future__ import annotations

import numpy as np

from besman.core.validation import SEED

SEEDS = 2**32  # seeds are 0 .. SEEDS - 1


def child_seed(seed: int, *keys: int) -> int:
    """The seed of part ``keys`` (non-negative integers) of a computation seeded with ``seed``, in
    0 .. 2**32 - 1: the same arguments give the same seed, other keys or another seed an unrelated one."""
    entropy = SEED("seed", seed)
    return int(np.random.SeedSequence(entropy, spawn_key=keys).generate_state(1)[0])


def cma_seed(seed: int) -> int:
    """pycma's seed for ``seed``, in 1 .. 2**32 - 1: pycma takes 0 for "draw one at random", so 0 .. 2**32 - 2
    become 1 .. 2**32 - 1 (the searches seeded so far keep their samples) and 2**32 - 1 wraps around to 1,
    searching as 0 does (pycma has one seed fewer than numpy)."""
    return seed % (SEEDS - 1) + 1
