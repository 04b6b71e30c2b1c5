"""Planning: recipe -> ordered work units -> shard groups. Decided once, before any work, by a fixed rule.

A unit's shard depends only on its position in the plan, never on completion order, so every executor
(1 worker, N workers, Ray) writes the same bytes.
"""

from __future__ import annotations

import hashlib
from dataclasses import dataclass

import numpy as np

from refspatial_gen.recipe import Recipe
from refspatial_gen.sources import get_source


@dataclass(frozen=True)
class Unit:
    uid: str  # globally unique in the run: "s<source index>/<source unit key>"
    source_index: int
    kind: str
    key: str  # the source's own unit key


@dataclass(frozen=True)
class Group:
    index: int
    units: tuple[Unit, ...]

    @property
    def name(self) -> str:
        return f"shard-{self.index:05d}"


def split_by_weight(total: int, weights: list[float]) -> list[int]:
    """Largest-remainder split of `total` units by weight (deterministic, sums exactly to total)."""
    w = np.asarray(weights, dtype=float)
    if w.sum() <= 0:
        raise ValueError("source weights sum to zero")
    exact = total * w / w.sum()
    base = np.floor(exact).astype(int)
    order = np.argsort(-(exact - base), kind="stable")
    base[order[: total - base.sum()]] += 1
    return base.tolist()


def plan_units(recipe: Recipe) -> list[Unit]:
    weighted = [s for s in recipe.sources if s.scenes is None]
    fixed_total = sum(s.scenes for s in recipe.sources if s.scenes is not None)
    counts = dict(zip([s.index for s in weighted],
                      split_by_weight(max(recipe.scenes - fixed_total, 0), [s.weight for s in weighted]) if weighted else []))
    units: list[Unit] = []
    for s in recipe.sources:
        n = s.scenes if s.scenes is not None else counts[s.index]
        if n == 0:
            continue
        keys = get_source(s.kind).unit_keys(s.config, n, s.input)
        units.extend(Unit(f"s{s.index}/{k}", s.index, s.kind, k) for k in keys[:n])
    uids = [u.uid for u in units]
    if len(set(uids)) != len(uids):
        raise ValueError("source produced duplicate unit keys")
    return units


def plan_groups(units: list[Unit], samples_per_shard: int) -> list[Group]:
    return [Group(i // samples_per_shard, tuple(units[i : i + samples_per_shard]))
            for i in range(0, len(units), samples_per_shard)]


def unit_rng(seed: int, uid: str) -> np.random.Generator:
    """The unit's own generator, from (run seed, unit id) only."""
    digest = hashlib.sha256(uid.encode("utf-8")).digest()
    words = np.frombuffer(digest[:16], dtype="<u4").tolist()
    return np.random.default_rng(np.random.SeedSequence([seed, *words]))
