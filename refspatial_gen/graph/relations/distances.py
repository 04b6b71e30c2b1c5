"""Metric distances: distance, touching, far from, next to (pairs), close/far to an anchor (derived),
and depth from the camera (per object).

Why surface distances: "the cup next to the plate" is about the gap between them, not their centres
(a long table's centre is far from a cup standing at its end). Centre distances are kept in node
attributes for questions that ask for them.
"""

from __future__ import annotations

import math
from collections.abc import Callable
from typing import TYPE_CHECKING, Any

import numpy as np

from refspatial_gen.core.model import RelationFact
from refspatial_gen.graph.constants import Thresholds
from refspatial_gen.graph.relations.base import Cell, Relation, decide, register
from refspatial_gen.graph.relations.common import (
    TRUE,
    UNDECIDED,
    Matrices,
    band_matrix,
    cached,
    fact,
    pair_facts,
    pos,
)
from refspatial_gen.graph.relations.lookup import stored_cell, symmetric_cell, symmetric_table
from refspatial_gen.graph.scene import SceneGeom

if TYPE_CHECKING:
    from refspatial_gen.graph.tables import RelationTables

G = ("gravity",)


def _distance(geom: SceneGeom) -> Matrices:
    def f(g: SceneGeom) -> Matrices:
        d = g.surface_distance
        codes = np.full(d.shape, TRUE, dtype=np.int8)
        return d, codes, np.maximum(0.01, g.th.quantity_tolerance * d)

    return cached(geom, "dist:distance", f)


def _touching(geom: SceneGeom) -> Matrices:
    def f(g: SceneGeom) -> Matrices:
        d = g.surface_distance
        th = g.th
        return d, band_matrix(d, th.touch_distance, th.touch_distance + th.touch_band), th.touch_band

    return cached(geom, "dist:touching", f)


def _far_from(geom: SceneGeom) -> Matrices:
    def f(g: SceneGeom) -> Matrices:
        d = g.surface_distance
        th = g.th
        # far_from holds when d is large: reuse band_matrix on the negated distance
        codes = band_matrix(-d, -(th.far_from_distance + th.far_from_band), -(th.far_from_distance - th.far_from_band))
        return d, codes, th.far_from_band

    return cached(geom, "dist:far_from", f)


def _next_to(geom: SceneGeom) -> Matrices:
    def f(g: SceneGeom) -> Matrices:
        d = g.surface_distance
        th = g.th
        codes = band_matrix(d, th.next_to_distance, th.next_to_distance + th.distance_margin)
        # side by side means sharing a height range; a stack is "on", not "next to": undecided
        lo, hi = g.lo[:, 2], g.hi[:, 2]
        common = np.minimum(hi[:, None], hi[None, :]) - np.maximum(lo[:, None], lo[None, :])
        smaller = np.minimum(g.height[:, None], g.height[None, :])
        codes[(codes == TRUE) & (common < 0.3 * smaller)] = UNDECIDED
        return d, codes, th.distance_margin

    return cached(geom, "dist:next_to", f)


def _sym_eval(matrices: Callable[[SceneGeom], Matrices], rel: str) -> Callable[..., RelationFact]:
    def evaluate(geom: SceneGeom, a: Any, b: Any) -> RelationFact:
        i, j = pos(geom, a), pos(geom, b)
        v, codes, m = matrices(geom)
        mm = float(np.broadcast_to(np.asarray(m, float), v.shape)[i, j])
        return fact(rel, (a, b), codes[i, j] if i != j else UNDECIDED, v[i, j], mm)

    return evaluate


def close_margin(d_ac: float, d_bc: float, th: Thresholds) -> float:
    """The gap close/far need: distance_margin, and distance_margin_rel of the larger of the two distances (a
    person cannot tell 1.9 m from 2.1 m: audit round 2)."""
    return max(th.distance_margin, th.distance_margin_rel * max(d_ac, d_bc))


def close_value(
    d_ac: float, d_bc: float, th: Thresholds, c_ac: float | None = None, c_bc: float | None = None
) -> tuple[bool | None, float, float]:
    """close(A, B, C): A is closer to C than B is; (decision, value = d(B, C) - d(A, C), margin). With the
    centre distances c_*, the decision holds only when the centres order A and B the same way by their own
    margin: a person judges by where the objects are, and a mouse lying in a tray is 0 m from it by surfaces
    (audit round 3)."""
    v = d_bc - d_ac
    m = close_margin(d_ac, d_bc, th)
    holds = decide(v, m)
    if holds is not None and c_ac is not None and c_bc is not None:
        if decide(c_bc - c_ac, close_margin(c_ac, c_bc, th)) is not holds:
            holds = None
    return holds, v, m


def centre_agrees(c_best: float, c_other: float, farthest: bool, th: Thresholds) -> bool:
    """The centre distances put the surface winner ahead of another candidate by their own close margin."""
    gap = (c_best - c_other) if farthest else (c_other - c_best)
    return bool(gap > close_margin(c_best, c_other, th))


def nested(t: RelationTables, *ids: Any) -> bool:
    """The first object and any other lie one inside the other (stored inside true or undecided)."""
    for x in ids[1:]:
        for pair in ((ids[0], x), (x, ids[0])):
            c = t.cell("inside", pair)
            if c is not None and c.holds is not False:
                return True
    return False


def linked(support_a: str | None, a: Any, support_b: str | None, b: Any) -> bool:
    """A stands on B or B on A (a stored node's `support`, "obj:<id>"): their distance is 0 by construction
    and says nothing a person would call "close" (the mouse in the tray)."""
    return support_a == f"obj:{b}" or support_b == f"obj:{a}"


def _count_close(geom: SceneGeom) -> list[RelationFact]:
    """Stores nothing (close/far are derived from stored distances); counts in graph.meta["truth"] the
    (A, B, anchor) triples, A and B unordered, whose distances to the anchor differ by more than
    distance_margin but not by distance_margin_rel of the larger (`distance_undecided_ratio`)."""
    d = geom.surface_distance
    n = geom.n
    if n < 3:
        return []
    th = geom.th
    dac, dbc = d[:, None, :], d[None, :, :]  # [a, b, c]
    gap = np.abs(dbc - dac)
    rel = (gap > th.distance_margin) & (gap <= th.distance_margin_rel * np.maximum(dac, dbc))
    distinct = (np.arange(n)[:, None] < np.arange(n)[None, :])[:, :, None]
    distinct = distinct & ~np.eye(n, dtype=bool)[:, None, :] & ~np.eye(n, dtype=bool)[None, :, :]
    ok = distinct & np.isfinite(dac) & np.isfinite(dbc)
    k = int(np.count_nonzero(rel & ok))
    c = geom.center_distance
    cac, cbc = c[:, None, :], c[None, :, :]
    sm = np.maximum(th.distance_margin, th.distance_margin_rel * np.maximum(dac, dbc))
    cm = np.maximum(th.distance_margin, th.distance_margin_rel * np.maximum(cac, cbc))
    s_dec = np.sign(dbc - dac) * (np.abs(dbc - dac) > sm)
    c_dec = np.sign(cbc - cac) * (np.abs(cbc - cac) > cm)
    kc = int(np.count_nonzero(ok & (s_dec != 0) & (c_dec != s_dec)))
    truth = geom.cache.setdefault("truth", {})
    if k:
        truth["distance_undecided_ratio"] = truth.get("distance_undecided_ratio", 0) + k
    if kc:
        truth["distance_centre_disagrees"] = truth.get("distance_centre_disagrees", 0) + kc
    return []


def _supported_pairs(geom: SceneGeom) -> set[tuple[int, int]]:
    """Positions (i, k) where i stands on object k or k on i (graph.support's rule, recomputed), or one lies
    inside the other (inside true or undecided: the mouse in the tray)."""
    from refspatial_gen.graph.relations.containment import _inside
    from refspatial_gen.graph.support import get_supports

    sup, _ = get_supports(geom)
    codes = _inside(geom)[1]
    out: set[tuple[int, int]] = set()
    for i, k in zip(*np.nonzero((codes == TRUE) | (codes == UNDECIDED))):
        if i != k:
            out.update({(int(i), int(k)), (int(k), int(i))})
    for i, s in enumerate(sup):
        if s is not None and s.kind == "object":
            k = geom.index[int(s.ref)]
            out.update({(i, k), (k, i)})
    return out


def _close_eval(mirror: bool) -> Callable[..., RelationFact]:
    def evaluate(geom: SceneGeom, a: Any, b: Any, c: Any) -> RelationFact:
        if len({a, b, c}) < 3:
            raise ValueError("close/far need three different objects")
        i, j, k = pos(geom, a), pos(geom, b), pos(geom, c)
        if mirror:
            i, j = j, i
        d, c = geom.surface_distance, geom.center_distance
        holds, v, m = close_value(float(d[i, k]), float(d[j, k]), geom.th, float(c[i, k]), float(c[j, k]))
        sup = cached(geom, "dist:supported", _supported_pairs)
        if (i, k) in sup or (j, k) in sup:
            holds = None
        return RelationFact("far" if mirror else "close", (a, b, c), holds, v, m)

    return evaluate


def _depth_eval(geom: SceneGeom, a: Any) -> RelationFact:
    i = pos(geom, a)
    return _depth_fact(geom, i)


def _depth_fact(geom: SceneGeom, i: int) -> RelationFact:
    """Depth of an object: median metric depth of its visible pixels. Undecided when the object spans
    more depth than the accepted error (a long sofa seen end-on has no single distance)."""
    v = geom.mask_depth[i]
    if not np.isfinite(v):
        v = float(geom.center_depth[i])
        m = geom.th.quantity_tolerance * max(v, 1e-6)
        return RelationFact("depth", (int(geom.ids[i]),), None, v, m)
    m = geom.th.quantity_tolerance * v
    ok = geom.mask_depth_spread[i] <= 2 * m
    return RelationFact("depth", (int(geom.ids[i]),), True if ok else None, float(v), float(m))


def _depth_stored(geom: SceneGeom) -> list[RelationFact]:
    return [_depth_fact(geom, i) for i in np.argsort(geom.ids, kind="stable")]


def _stored(
    rel: str, matrices: Callable[[SceneGeom], Matrices], sparse: bool
) -> Callable[[SceneGeom], list[RelationFact]]:
    return lambda geom: pair_facts(rel, geom, *matrices(geom), only={TRUE, UNDECIDED} if sparse else None)


def _close_cell(t: RelationTables, args: tuple[Any, ...]) -> Cell | None:
    """close(A, B, C) from the stored surface distances (far is its mirror: close(B, A, C))."""
    if t.th is None:
        return None
    d, pos = t.distance_rows(), t.pos
    a, b, c = pos.get(args[0]), pos.get(args[1]), pos.get(args[2])
    if a is None or b is None or c is None:
        return None
    dac, dbc = d[a][c], d[b][c]
    if dac == _INF or dbc == _INF:
        return None
    ids = (args[0], args[1], args[2])
    ctr = [t.nodes[x].attributes.get("center") for x in ids]
    cac = cbc = None
    if ctr[0] is not None and ctr[1] is not None and ctr[2] is not None:
        cac, cbc = math.dist(ctr[0], ctr[2]), math.dist(ctr[1], ctr[2])
    holds, v, m = close_value(dac, dbc, t.th, cac, cbc)
    sa, sb, sc = (t.nodes[x].support for x in ids)
    if linked(sa, ids[0], sc, ids[2]) or linked(sb, ids[1], sc, ids[2]) or nested(t, ids[2], ids[0], ids[1]):
        holds = None
    return Cell(holds, v, m)


_INF = float("inf")
register(
    Relation(
        "close",
        "distances",
        "world",
        3,
        "d(B, C) minus d(A, C), surface distances (m)",
        "distance_margin, distance_margin_rel",
        "A is closer to the anchor C than B is (nearest-surface distances), by distance_margin and by "
        "distance_margin_rel of the larger distance",
        storage="derived",
        needs=G,
        qa="anchored",
        evaluate=_close_eval(False),
        stored=_count_close,
        cell=_close_cell,
    )
)
register(
    Relation(
        "far",
        "distances",
        "world",
        3,
        "d(A, C) minus d(B, C), surface distances (m)",
        "distance_margin, distance_margin_rel",
        "mirror of close: A is farther from the anchor C than B is",
        storage="derived",
        mirror_of="close",
        needs=G,
        qa="anchored",
        evaluate=_close_eval(True),
    )
)
register(
    Relation(
        "depth",
        "distances",
        "cam",
        1,
        "median metric depth of A's visible pixels (m)",
        "quantity_tolerance",
        "the metric distance from the camera to the object (undecided when it spans more depth than the tolerance)",
        storage="unary",
        evaluate=_depth_eval,
        stored=_depth_stored,
        cell=stored_cell("depth"),
    )
)
register(
    Relation(
        "distance",
        "distances",
        "world",
        2,
        "minimum surface-to-surface distance (m)",
        "quantity_tolerance",
        "metric distance between two objects' nearest surfaces (centre distance in node attributes)",
        storage="symmetric",
        needs=G,
        evaluate=_sym_eval(_distance, "distance"),
        stored=_stored("distance", _distance, False),
        cell=symmetric_cell("distance", None),
    )
)


def _contact(
    rid: str,
    matrices: Callable[[SceneGeom], Matrices],
    absent: Callable[[Thresholds], float],
    margin: str,
    definition: str,
    spec: bool = True,
) -> None:
    """A sparse symmetric distance relation: absent instances of a pair with a distance are False."""
    register(
        Relation(
            rid,
            "distances",
            "world",
            2,
            "minimum surface distance (m)",
            margin,
            definition,
            storage="sparse",
            needs=G,
            spec=spec,
            qa="pairwise",
            evaluate=_sym_eval(matrices, rid),
            stored=_stored(rid, matrices, True),
            cell=symmetric_cell(rid, absent),
            table=symmetric_table(rid),
        )
    )


_contact(
    "touching",
    _touching,
    lambda th: th.touch_band,
    "touch_distance, touch_band",
    "the objects' surfaces are within the touch distance (source-dependent: 1 cm sim, 5 cm scans)",
)
_contact(
    "far_from",
    _far_from,
    lambda th: th.far_from_band,
    "far_from_distance, far_from_band",
    "the objects' nearest surfaces are farther apart than the scene-scaled distance (0.3 m tabletop, 2 m room)",
)
_contact(
    "next_to",
    _next_to,
    lambda th: th.distance_margin,
    "next_to_distance, distance_margin",
    "the objects stand side by side (sharing a height range) with a small gap",
    spec=False,
)
