"""Helpers shared by relation groups: decision matrices and turning them into facts."""

from __future__ import annotations

from collections.abc import Callable
from typing import Any

import numpy as np

from refspatial_gen.core.model import RelationFact
from refspatial_gen.graph.scene import SceneGeom

TRUE, FALSE, UNDECIDED = 1, 0, -1
# (value, codes, margin) matrices of a pair relation over object positions
Matrices = tuple[Any, Any, Any]


def decide_matrix(v: np.ndarray, margin: np.ndarray | float) -> np.ndarray:
    """int8 decisions: 1 where v > margin, 0 where v < -margin, -1 inside the band."""
    out = np.full(np.shape(v), UNDECIDED, dtype=np.int8)
    out[v > margin] = TRUE
    out[v < -np.asarray(margin)] = FALSE
    return out


def band_matrix(v: np.ndarray, low: np.ndarray | float, high: np.ndarray | float) -> np.ndarray:
    """int8 decisions: 1 where v < low, 0 where v > high, -1 between."""
    out = np.full(np.shape(v), UNDECIDED, dtype=np.int8)
    out[v < low] = TRUE
    out[v > high] = FALSE
    return out


def holds_of(code: int) -> bool | None:
    return None if code == UNDECIDED else bool(code == TRUE)


def fact(rel: str, args: tuple[Any, ...], code: int, value: float, margin: float) -> RelationFact:
    return RelationFact(rel, tuple(args), holds_of(int(code)), float(value), float(margin))


def ordered_pairs_by_id(ids: np.ndarray) -> list[tuple[int, int]]:
    """Position pairs (i, j) with ids[i] < ids[j], sorted by id (deterministic storage order)."""
    order = np.argsort(ids, kind="stable")
    return [(int(order[a]), int(order[b])) for a in range(len(order)) for b in range(a + 1, len(order))]


def pair_facts(
    rel: str,
    geom: SceneGeom,
    value: np.ndarray,
    codes: np.ndarray,
    margin: np.ndarray | float,
    only: set[int] | None = None,
) -> list[RelationFact]:
    """One fact per unordered pair (lower id first). `only`: keep these codes (sparse storage)."""
    m = np.broadcast_to(np.asarray(margin, float), value.shape)
    out = []
    for i, j in ordered_pairs_by_id(geom.ids):
        c = int(codes[i, j])
        if only is not None and c not in only:
            continue
        out.append(fact(rel, (int(geom.ids[i]), int(geom.ids[j])), c, value[i, j], m[i, j]))
    return out


def pos(geom: SceneGeom, object_id: Any) -> int:
    try:
        return geom.index[int(object_id)]
    except (KeyError, TypeError, ValueError):
        raise KeyError(f"frame {geom.frame.frame_id} has no object {object_id!r}") from None


def count(geom: SceneGeom, reason: str, mask: np.ndarray) -> None:
    """Add the unordered pairs of `mask` (an (n, n) bool matrix, either order counting once) to
    graph.meta["truth"][reason]: pairs a clear-margin rule made undecided (run report, "Truth checks")."""
    n = int(np.count_nonzero(np.triu(mask | mask.T, 1)))
    if n:
        truth = geom.cache.setdefault("truth", {})
        truth[reason] = truth.get(reason, 0) + n


def cached(geom: SceneGeom, key: str, fn: Callable[[SceneGeom], Any]) -> Any:
    if key not in geom.cache:
        geom.cache[key] = fn(geom)
    return geom.cache[key]


def pair_evaluator(
    matrices: Callable[[SceneGeom], Matrices], canonical: str, mirror: str | None = None
) -> Callable[..., RelationFact]:
    """evaluate(geom, a, b) for a pair relation whose matrices(geom) -> (value, codes, margin).
    With `mirror` set, evaluates the mirror relation: mirror(a, b) = canonical(b, a)."""

    def evaluate(geom: SceneGeom, a: Any, b: Any) -> RelationFact:
        i, j = pos(geom, a), pos(geom, b)
        if mirror:
            i, j = j, i
        v, codes, m = matrices(geom)
        mm = float(np.broadcast_to(np.asarray(m, float), v.shape)[i, j])
        return fact(mirror or canonical, (a, b), codes[i, j], v[i, j], mm)

    return evaluate
