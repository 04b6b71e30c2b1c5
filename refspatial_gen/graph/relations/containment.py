"""Containment and betweenness: inside / outside (share of A's volume in B's box) and between.

Why "between" is undecided when a same-category object is also between: "the cup between the plate
and the bowl" must pick out one cup; when two qualify the question is not asked (spec rule 12).
"""

from __future__ import annotations

import numpy as np

from refspatial_gen.core.geometry import inside_fraction
from refspatial_gen.core.model import RelationFact
from refspatial_gen.graph.relations.base import Relation, register
from refspatial_gen.graph.relations.common import FALSE, TRUE, UNDECIDED, band_matrix, cached, fact, pos

G = ("gravity",)
MIN_BETWEEN_SPAN = 0.05  # m; anchors closer than this span no "between" region


def _inside(geom):
    def f(g):
        n = g.n
        frac = np.zeros((n, n))
        # only pairs whose boxes overlap can have volume inside one another
        overlap = np.all(g.lo[:, None, :] < g.hi[None, :, :], axis=2) & np.all(g.lo[None, :, :] < g.hi[:, None, :], axis=2)
        for i, j in zip(*np.nonzero(overlap)):
            if i != j:
                frac[i, j] = inside_fraction(g.boxes[i], g.boxes[j], n=8)
        th = g.th
        codes = band_matrix(-frac, -(th.inside_fraction + th.inside_band), -(th.inside_fraction - th.inside_band))
        np.fill_diagonal(codes, UNDECIDED)
        return frac, codes, th.inside_band
    return cached(geom, "contain:inside", f)


def between_table(xy: np.ndarray, ids: np.ndarray, categories: list[str], dist: np.ndarray, th) -> dict:
    """{(a, b, c) positions: (code, t)} for anchors b, c with ids[b] < ids[c}; False instances omitted.
    Shared by the geometry and the query index (which passes stored node centres and distances)."""
    n = len(ids)
    out: dict[tuple[int, int, int], tuple[int, float]] = {}
    for b in range(n):
        for c in range(n):
            if b == c or ids[b] > ids[c]:
                continue
            seg = xy[c] - xy[b]
            L = float(np.linalg.norm(seg))
            if L < MIN_BETWEEN_SPAN:
                continue
            u = seg / L
            rel = xy - xy[b]
            t = rel @ u / L
            lat = np.abs(rel @ np.array([-u[1], u[0]]))
            corridor = th.between_corridor * L
            yes = (t > th.between_t_margin) & (t < 1 - th.between_t_margin) & (lat < corridor)
            no = (t < 0) | (t > 1) | (lat > 1.5 * corridor)
            clear = (dist[:, b] > 1e-6) & (dist[:, c] > 1e-6)
            for a in np.flatnonzero(~no):
                if a in (b, c):
                    continue
                out[(int(a), b, c)] = (TRUE if (yes[a] and clear[a]) else UNDECIDED, float(t[a]))
    # a second object of A's category also (possibly) between B and C makes A ambiguous
    by_anchor: dict[tuple[int, int], list[int]] = {}
    for (a, b, c) in out:
        by_anchor.setdefault((b, c), []).append(a)
    for (b, c), members in by_anchor.items():
        for a in members:
            if out[(a, b, c)][0] == TRUE and any(categories[o] == categories[a] for o in members if o != a):
                out[(a, b, c)] = (UNDECIDED, out[(a, b, c)][1])
    return out


def _between(geom):
    return cached(geom, "contain:between",
                  lambda g: between_table(g.centers[:, :2], g.ids, g.categories, g.surface_distance, g.th))


def facts(geom) -> list[RelationFact]:
    if not geom.world_ok:
        return []
    out = []
    frac, codes, m = _inside(geom)
    order = np.argsort(geom.ids, kind="stable")
    for i in order:
        for j in order:
            if i != j and codes[i, j] != FALSE:
                out.append(fact("inside", (int(geom.ids[i]), int(geom.ids[j])), codes[i, j], frac[i, j], m))
    return out  # between is derived by the query index from node centres and distances (between_table)


def _inside_eval(negated: bool):
    def evaluate(geom, a, b) -> RelationFact:
        i, j = pos(geom, a), pos(geom, b)
        frac, codes, m = _inside(geom)
        f = fact("inside", (a, b), codes[i, j], frac[i, j], m)
        if negated:
            return RelationFact("outside", (a, b), None if f.holds is None else not f.holds, f.value, f.margin)
        return f
    return evaluate


def _between_eval(geom, a, b, c) -> RelationFact:
    i, j, k = pos(geom, a), pos(geom, b), pos(geom, c)
    if geom.ids[j] > geom.ids[k]:
        j, k = k, j
    code, t = _between(geom).get((i, j, k), (FALSE, 0.0))
    return fact("between", (a, b, c), code, t, geom.th.between_t_margin)


register(Relation("inside", "containment", "world", 2, "share of A's box volume inside B's box", "inside_fraction, inside_band",
                  "more than 30% of A's volume lies inside B's box", storage="sparse", needs=G, evaluate=_inside_eval(False)))
register(Relation("outside", "containment", "world", 2, "share of A's box volume inside B's box", "inside_fraction, inside_band",
                  "less than 30% of A's volume lies inside B's box", storage="derived", negation_of="inside", needs=G,
                  evaluate=_inside_eval(True)))
register(Relation("between", "containment", "world", 3, "position of A's centre along the B-C segment (0 at B, 1 at C)",
                  "between_t_margin, between_corridor",
                  "A's centre lies in the corridor spanned by B and C (ground plane), and no other object of A's category does",
                  storage="derived", needs=G, evaluate=_between_eval))
