"""Gravity-frame vertical relations: above/below (world), on / supported by, under.

Why: "above from the real-world perspective" needs gravity, not image rows. A resting stack (A's bottom
at B's top) counts as above whatever the centre heights; otherwise centres must differ by the margin.
"""

from __future__ import annotations

import numpy as np

from refspatial_gen.core.model import RelationFact
from refspatial_gen.graph.relations.base import Relation, register
from refspatial_gen.graph.relations.common import (FALSE, TRUE, UNDECIDED, cached, decide_matrix, fact, pair_evaluator,
                                                   pair_facts, pos)
from refspatial_gen.graph.support import get_supports

G = ("gravity",)


def _above(geom):
    def f(g):
        cz = g.centers[:, 2]
        v = cz[:, None] - cz[None, :]  # v[i, j] > 0: i's centre higher
        tol = g.th.stack_tolerance
        codes = decide_matrix(v, g.th.vertical_margin)
        stacked = g.lo[:, None, 2] >= g.hi[None, :, 2] - tol  # i's bottom at or above j's top
        codes[stacked & (v > 0)] = TRUE
        codes[stacked.T & (v < 0)] = FALSE
        np.fill_diagonal(codes, UNDECIDED)
        return v, codes, g.th.vertical_margin
    return cached(geom, "vert:above", f)


def _under(geom):
    """under[i, j]: i's top at or below j's bottom, with their footprints overlapping."""
    def f(g):
        tol = g.th.stack_tolerance
        below = g.hi[:, None, 2] <= g.lo[None, :, 2] + tol
        share = np.maximum(g.footprint_overlap, g.footprint_overlap.T)  # share of the smaller footprint covered
        v = share
        codes = np.full(v.shape, FALSE, dtype=np.int8)
        codes[below & (share >= 0.3)] = TRUE
        codes[below & (share >= 0.15) & (share < 0.3)] = UNDECIDED
        np.fill_diagonal(codes, FALSE)
        return v, codes, 0.15
    return cached(geom, "vert:under", f)


def on_fact(geom, a, b) -> RelationFact:
    """on(A, B): B is A's support (B an object id or a surface id)."""
    i = pos(geom, a)
    sup, _ = get_supports(geom)
    s = sup[i]
    target = b if isinstance(b, str) else int(b)
    holds = s is not None and s.ref == target
    return RelationFact("on", (a, b), holds, 0.0 if s is None else s.gap, geom.th.support_gap)


def supported_by_fact(geom, a, b) -> RelationFact:
    f = on_fact(geom, a, b)
    return RelationFact("supported_by", f.args, f.holds, f.value, f.margin)


def facts(geom) -> list[RelationFact]:
    if not geom.world_ok:
        return []
    out = pair_facts("above_world", geom, *_above(geom))
    sup, _ = get_supports(geom)
    order = np.argsort(geom.ids, kind="stable")
    for i in order:
        s = sup[i]
        if s is not None:
            out.append(RelationFact("on", (int(geom.ids[i]), s.ref), True, s.gap, geom.th.support_gap))
    v, codes, m = _under(geom)
    for i in order:
        for j in order:
            if i != j and codes[i, j] != FALSE:
                out.append(fact("under", (int(geom.ids[i]), int(geom.ids[j])), codes[i, j], v[i, j], m))
    return out


def _under_eval(geom, a, b) -> RelationFact:
    i, j = pos(geom, a), pos(geom, b)
    v, codes, m = _under(geom)
    return fact("under", (a, b), codes[i, j], v[i, j], m)


register(Relation("above_world", "vertical", "world", 2, "centre height of A minus B's (m)", "vertical_margin, stack_tolerance",
                  "A's bottom is at or above B's top, or A's centre is higher by the margin (gravity frame)",
                  needs=G, evaluate=pair_evaluator(_above, "above_world")))
register(Relation("below_world", "vertical", "world", 2, "centre height of B minus A's (m)", "vertical_margin, stack_tolerance",
                  "mirror of above (world): A is lower than B in the gravity frame", mirror_of="above_world", needs=G,
                  evaluate=pair_evaluator(_above, "above_world", "below_world")))
register(Relation("on", "support", "world", 2, "A's bottom minus the support's top (m)", "support_gap, support_overlap",
                  "A rests on B (an object or a support surface id): B's top is within the gap of A's bottom and covers A's footprint",
                  storage="sparse", needs=G, spec=False, evaluate=on_fact))
register(Relation("supported_by", "support", "world", 2, "A's bottom minus the support's top (m)", "support_gap, support_overlap",
                  "same instances as on: A is supported by B", storage="derived", needs=G, spec=False,
                  evaluate=supported_by_fact))
register(Relation("under", "support", "world", 2, "share of the smaller footprint the two overlap", "stack_tolerance",
                  "A's top is at or below B's bottom and their footprints overlap (30%; 15-30% undecided)",
                  storage="sparse", needs=G, spec=False, evaluate=_under_eval))
