"""The random draws of one sample's QA generation, from Python's Mersenne Twister.

Why not the sample's numpy Generator directly: the engine makes a few hundred tiny draws per sample (family
and template picks, slot shuffles, wording variants, answer letters), and each numpy call costs about a
microsecond of call overhead, ten times the draw. This generator is seeded from one draw of the sample's
numpy Generator, so the run stays reproducible per (recipe seed, unit key), and it only uses
`random.random()`, whose sequence for a given seed Python guarantees across versions (shuffles and samples
are built on it here, not on `random.shuffle`/`sample`, whose algorithms may change).
"""

from __future__ import annotations

import random
from collections.abc import Sequence
from typing import Any

import numpy as np


class SampleRng:
    """The subset of numpy.random.Generator the QA engine uses: integers(n), random(), permutation(n),
    choice(n, size, replace=False); integers and arrays come back as Python ints and lists."""

    __slots__ = ("random",)

    def __init__(self, rng: np.random.Generator) -> None:
        self.random = random.Random(int(rng.integers(2**63))).random

    def integers(self, n: int) -> int:
        """Uniform in [0, n) (53-bit float scaled: bias below 1e-15 for the small n used here)."""
        return int(self.random() * n)

    def permutation(self, n: int) -> list[int]:
        """A uniformly random order of range(n)."""
        return self.shuffled(range(n))

    def shuffled(self, items: Sequence[Any]) -> list[Any]:
        """A new list of `items` in a uniformly random order (Fisher-Yates): the same draws and the same order
        as [items[k] for k in permutation(len(items))]."""
        p = list(items)
        r = self.random
        for i in range(len(p) - 1, 0, -1):
            j = int(r() * (i + 1))
            p[i], p[j] = p[j], p[i]
        return p

    def choice(self, n: int, size: int, replace: bool = False) -> list[int]:
        """`size` distinct indices of range(n) in random order (a partial Fisher-Yates)."""
        if replace:
            raise ValueError("SampleRng.choice draws without replacement only")
        if size > n:
            raise ValueError(f"cannot draw {size} of {n} without replacement")
        p = list(range(n))
        r = self.random
        for i in range(size):
            j = i + int(r() * (n - i))
            p[i], p[j] = p[j], p[i]
        return p[:size]
