"""Gravity-frame vertical relations: above/below (world), on / supported by, under.

Why: "above from the real-world perspective" needs gravity, not image rows. A resting stack (A's bottom
at B's top) counts as above whatever the centre heights; otherwise centres must differ by the margin. Beside
B rather than over it, A must also clear B's top by a visible gap (graph/relations/vertical_clear.py).
"""

from __future__ import annotations

from typing import TYPE_CHECKING, Any

import numpy as np

from refspatial_gen.core.model import RelationFact
from refspatial_gen.graph.relations.base import Cell, Relation, register
from refspatial_gen.graph.relations.common import (
    FALSE,
    TRUE,
    UNDECIDED,
    Matrices,
    cached,
    count,
    decide_matrix,
    fact,
    pair_evaluator,
    pair_facts,
    pos,
)
from refspatial_gen.graph.relations.lookup import false_absent, pair_cell, pair_table, sparse_cell, sparse_table
from refspatial_gen.graph.relations.vertical_clear import apply_clear_margin
from refspatial_gen.graph.scene import SceneGeom
from refspatial_gen.graph.support import get_supports

if TYPE_CHECKING:
    from refspatial_gen.graph.tables import RelationTables

G = ("gravity",)


def _above(geom: SceneGeom) -> Matrices:
    def f(g: SceneGeom) -> Matrices:
        cz = g.centers[:, 2]
        v = cz[:, None] - cz[None, :]  # v[i, j] > 0: i's centre higher
        tol = g.th.stack_tolerance
        codes = decide_matrix(v, g.th.vertical_margin)
        stacked = g.lo[:, None, 2] >= g.hi[None, :, 2] - tol  # i's bottom at or above j's top
        # both ways round (two objects thinner than the tolerance, side by side at one level): no stack, or
        # the sign of a rounding-sized centre difference would decide which is "above"
        stacked &= ~stacked.T
        # side by side with overlapping heights (a tall lamp by a short cup) is not "above", however the
        # centres differ; a resting stack may overlap by the tolerance
        overlap = np.minimum(g.hi[:, None, 2], g.hi[None, :, 2]) - np.maximum(g.lo[:, None, 2], g.lo[None, :, 2])
        codes[overlap > tol] = UNDECIDED
        codes[stacked & (v > 0)] = TRUE
        codes[stacked.T & (v < 0)] = FALSE
        # bottoms at one level (a flat pen and a can on one tabletop, audit round 3): both rest on the same
        # surface, so neither is above the other, however thin one of them is
        same = np.abs(g.lo[:, None, 2] - g.lo[None, :, 2]) <= tol
        np.fill_diagonal(same, False)
        count(g, "vertical_same_level", same & (codes != UNDECIDED))
        codes[same] = UNDECIDED
        np.fill_diagonal(codes, UNDECIDED)
        apply_clear_margin(g, codes)  # beside, not over: a clear gap (vertical_beside_margin)
        return v, codes, g.th.vertical_margin

    return cached(geom, "vert:above", f)


def _under(geom: SceneGeom) -> Matrices:
    """under[i, j]: i's top at or below j's bottom, with their footprints overlapping."""

    def f(g: SceneGeom) -> Matrices:
        tol = g.th.stack_tolerance
        below = g.hi[:, None, 2] <= g.lo[None, :, 2] + tol
        share = np.maximum(g.footprint_overlap, g.footprint_overlap.T)  # share of the smaller footprint covered
        v = share
        codes = np.full(v.shape, FALSE, dtype=np.int8)
        codes[below & (share >= 0.3)] = TRUE
        codes[below & (share >= 0.15) & (share < 0.3)] = UNDECIDED
        np.fill_diagonal(codes, FALSE)
        return v, codes, UNDER_MARGIN

    return cached(geom, "vert:under", f)


def on_fact(geom: SceneGeom, a: Any, b: Any) -> RelationFact:
    """on(A, B): B is A's support (B an object id or a surface id)."""
    i = pos(geom, a)
    sup, _ = get_supports(geom)
    s = sup[i]
    target = b if isinstance(b, str) else int(b)
    holds = s is not None and s.ref == target
    return RelationFact("on", (a, b), holds, 0.0 if s is None else s.gap, geom.th.support_gap)


def supported_by_fact(geom: SceneGeom, a: Any, b: Any) -> RelationFact:
    f = on_fact(geom, a, b)
    return RelationFact("supported_by", f.args, f.holds, f.value, f.margin)


def _above_stored(geom: SceneGeom) -> list[RelationFact]:
    return pair_facts("above_world", geom, *_above(geom))


def _on_stored(geom: SceneGeom) -> list[RelationFact]:
    sup, _ = get_supports(geom)
    out = []
    for i in np.argsort(geom.ids, kind="stable"):
        s = sup[i]
        if s is not None:
            out.append(RelationFact("on", (int(geom.ids[i]), s.ref), True, s.gap, geom.th.support_gap))
    return out


def _under_stored(geom: SceneGeom) -> list[RelationFact]:
    order = np.argsort(geom.ids, kind="stable")
    v, codes, m = _under(geom)
    out = []
    for i in order:
        for j in order:
            if i != j and codes[i, j] != FALSE:
                out.append(fact("under", (int(geom.ids[i]), int(geom.ids[j])), codes[i, j], v[i, j], m))
    return out


def _under_eval(geom: SceneGeom, a: Any, b: Any) -> RelationFact:
    i, j = pos(geom, a), pos(geom, b)
    v, codes, m = _under(geom)
    return fact("under", (a, b), codes[i, j], v[i, j], m)


def _on_cell(t: RelationTables, args: tuple[Any, ...]) -> Cell | None:
    """on (and supported_by): the stored instance; absent = False unless the node's own support is B (then
    undecided: the builder chose not to store it)."""
    a, b = args
    f = t.stored("on", args)
    if f is not None:
        return Cell(f.holds, float(f.value), f.margin)
    if t.th is None:
        return None
    target = b if isinstance(b, str) else f"obj:{int(b)}"
    return Cell(False if t.nodes[int(a)].support != target else None, 0.0, t.th.support_gap)


def _on_domain(t: RelationTables) -> list[tuple[Any, ...]]:
    """(object, its support) for every supported object (a support names an object as "obj:<id>")."""
    out: list[tuple[Any, ...]] = []
    for i in t.ids:
        s = t.nodes[i].support
        if s is not None:
            out.append((i, int(s[4:]) if s.startswith("obj:") else s))
    return out


UNDER_MARGIN = 0.15  # share of the smaller footprint: the undecided band of under (15-30%)
register(
    Relation(
        "above_world",
        "vertical",
        "world",
        2,
        "centre height of A minus B's (m)",
        "vertical_margin, stack_tolerance, vertical_over_share, vertical_clear_margin, vertical_clear_share",
        "A is over B (footprints overlap by vertical_over_share) with its bottom at or above B's top, or beside "
        "B with its bottom above B's top by max(vertical_clear_margin, vertical_clear_share x B's height) "
        "(gravity frame); never when both bottoms are within the stack tolerance of each other (one surface)",
        needs=G,
        qa="ordered",
        evaluate=pair_evaluator(_above, "above_world"),
        stored=_above_stored,
        cell=pair_cell("above_world"),
        table=pair_table("above_world"),
    )
)
register(
    Relation(
        "below_world",
        "vertical",
        "world",
        2,
        "centre height of B minus A's (m)",
        "vertical_margin, stack_tolerance",
        "mirror of above (world): A is lower than B in the gravity frame",
        mirror_of="above_world",
        needs=G,
        qa="ordered",
        evaluate=pair_evaluator(_above, "above_world", "below_world"),
    )
)
register(
    Relation(
        "on",
        "support",
        "world",
        2,
        "A's bottom minus the support's top (m)",
        "support_gap, support_overlap",
        "A rests on B (an object or a support surface id): B's top is within the gap of A's bottom and "
        "covers A's footprint",
        storage="sparse",
        needs=G,
        spec=False,
        qa="pairwise",
        evaluate=on_fact,
        stored=_on_stored,
        cell=_on_cell,
        domain=_on_domain,
    )
)
register(
    Relation(
        "supported_by",
        "support",
        "world",
        2,
        "A's bottom minus the support's top (m)",
        "support_gap, support_overlap",
        "same instances as on: A is supported by B",
        storage="derived",
        needs=G,
        spec=False,
        evaluate=supported_by_fact,
        cell=_on_cell,
        domain=_on_domain,
    )
)
register(
    Relation(
        "under",
        "support",
        "world",
        2,
        "share of the smaller footprint the two overlap",
        "stack_tolerance",
        "A's top is at or below B's bottom and their footprints overlap (30%; 15-30% undecided)",
        storage="sparse",
        needs=G,
        spec=False,
        evaluate=_under_eval,
        stored=_under_stored,
        cell=sparse_cell("under", false_absent(lambda th: UNDER_MARGIN)),
        table=sparse_table("under"),
    )
)
