"""Containment and betweenness: inside / outside (share of A's volume in B's box) and between.

Why "between" is undecided when a same-category object is also between: "the cup between the plate
and the bowl" must pick out one cup; when two qualify the question is not asked (spec rule 12).
"""

from __future__ import annotations

from collections.abc import Callable
from typing import TYPE_CHECKING, Any

import numpy as np

from refspatial_gen.core.geometry import inside_fraction
from refspatial_gen.core.model import RelationFact
from refspatial_gen.graph.relations.base import Cell, Relation, register
from refspatial_gen.graph.relations.between_angle import angle_masks, near_anchor
from refspatial_gen.graph.relations.common import (
    FALSE,
    TRUE,
    UNDECIDED,
    Matrices,
    band_matrix,
    cached,
    fact,
    holds_of,
    pos,
)
from refspatial_gen.graph.relations.lookup import false_absent, sparse_cell, sparse_table
from refspatial_gen.graph.relations.receptacle import apply_receptacle_rule
from refspatial_gen.graph.scene import SceneGeom

if TYPE_CHECKING:
    from refspatial_gen.graph.tables import RelationTables

G = ("gravity",)
MIN_BETWEEN_SPAN = 0.05  # m; anchors closer than this span no "between" region
MIN_BETWEEN_PX = 8.0  # px; anchors closer than this in the image decide nothing there (undecided)


def _inside(geom: SceneGeom) -> Matrices:
    def f(g: SceneGeom) -> Matrices:
        n = g.n
        frac = np.zeros((n, n))
        # only pairs whose boxes overlap can have volume inside one another
        overlap = np.all(g.lo[:, None, :] < g.hi[None, :, :], axis=2) & np.all(
            g.lo[None, :, :] < g.hi[:, None, :], axis=2
        )
        for i, j in zip(*np.nonzero(overlap)):
            if i != j:
                frac[i, j] = inside_fraction(g.boxes[i], g.boxes[j], n=8)
        th = g.th
        codes = band_matrix(-frac, -(th.inside_fraction + th.inside_band), -(th.inside_fraction - th.inside_band))
        np.fill_diagonal(codes, UNDECIDED)
        # B must be a receptacle A fits in, A over its floor (audit round 4: "the bin in the desk")
        return frac, apply_receptacle_rule(g, codes), th.inside_band

    return cached(geom, "contain:inside", f)


def segment_position(
    xy: np.ndarray, B: np.ndarray, C: np.ndarray, th: Any, min_span: float
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """(t, yes, no) of every object against every anchor pair p in one plane: t[p, a] the position of a's
    projection along B[p] -> C[p] (0 at B, 1 at C); yes where a lies on the segment (t well inside, distance
    from the line below the corridor share of |BC|), no where it lies clearly off it; neither is undecided.
    Pairs spanning less than `min_span` decide nothing (their direction is noise)."""
    seg = xy[C] - xy[B]
    L = np.sqrt(seg[:, 0] * seg[:, 0] + seg[:, 1] * seg[:, 1])
    ok = L >= min_span
    u = seg / np.where(ok, L, 1.0)[:, None]
    rel = xy[None, :, :] - xy[B][:, None, :]  # rel[p, a] = A - B of anchor pair p
    Ls = np.where(ok, L, 1.0)[:, None]
    t = (rel[..., 0] * u[:, None, 0] + rel[..., 1] * u[:, None, 1]) / Ls
    lat = np.abs(rel[..., 1] * u[:, None, 0] - rel[..., 0] * u[:, None, 1]) / Ls
    m, cor = th.between_t_margin, th.between_corridor
    taper = np.minimum(1.0, np.minimum(t, 1 - t) / th.between_taper)
    yes = (t > m) & (t < 1 - m) & (lat < cor * taper) & ok[:, None]
    no = ((t < m - th.between_t_band) | (t > 1 - m + th.between_t_band) | (lat > cor + th.between_corridor_band)) & ok[
        :, None
    ]
    return t, yes, no


def between_parts(
    xy: np.ndarray, uv: np.ndarray, ids: np.ndarray, categories: list[str], dist: np.ndarray, th: Any
) -> dict[str, Any] | None:
    """Every anchor pair at once: {B, C, cand, code, t, between_angle, between_anchor_gap} with anchor
    positions B[p], C[p] (ids[B] < ids[C]), cand[p, a] = between(a, B[p], C[p]) is not False, code[p, a] its
    TRUE/UNDECIDED code, t[p, a] the position along the ground-plane segment, and the two reason masks of
    between_angle.count_between. A is between when it lies on the segment joining the anchors both on the
    ground plane (`xy`, centres in m) and in the image (`uv`, mask centroids in pixels), within the angular
    limit seen from each anchor in both (graph/relations/between_angle.py): the audit found ground-plane
    corridors alone answering with objects a person sees beside both anchors. None when no pair spans a region."""
    ids = np.asarray(ids)
    n = len(ids)
    if n < 3:
        return None
    xy = np.asarray(xy, float).reshape(n, 2)
    uv = np.asarray(uv, float).reshape(n, 2)
    B, C = np.nonzero(ids[:, None] < ids[None, :])  # row-major: the order of nested (b, c) loops
    seg = xy[C] - xy[B]
    span = np.sqrt(seg[:, 0] * seg[:, 0] + seg[:, 1] * seg[:, 1])
    keep = span >= MIN_BETWEEN_SPAN
    B, C, span = B[keep], C[keep], span[keep]
    if not len(B):
        return None
    t, yes_w, no_w = segment_position(xy, B, C, th, MIN_BETWEEN_SPAN)
    _ti, yes_i, no_i = segment_position(uv, B, C, th, MIN_BETWEEN_PX)
    in_w, out_w = angle_masks(xy, B, C, th)
    in_i, out_i = angle_masks(uv, B, C, th)
    seen = (np.hypot(*(uv[C] - uv[B]).T) >= MIN_BETWEEN_PX)[:, None]  # the image decides nothing otherwise
    corridor = yes_w & yes_i
    angled = in_w & in_i & seen
    no_w, no_i = no_w | out_w, no_i | (out_i & seen)
    yes = corridor & angled
    cand = ~(no_w | no_i)
    rival = ~(no_w & no_i)  # a same-category object is out of the running only when clearly off in both planes
    rows = np.arange(len(B))
    for m in (cand, rival, corridor, yes):
        m[rows, B] = False
        m[rows, C] = False
    close = near_anchor(np.asarray(dist, float), B, C, span, th)
    # a second object of A's category also (possibly) between B and C makes A ambiguous
    labels: dict[str, int] = {}
    cat = np.array([labels.setdefault(str(c), len(labels)) for c in categories])
    same = cat[:, None] == cat[None, :]
    np.fill_diagonal(same, False)
    ambiguous = (rival.astype(np.int64) @ same.astype(np.int64)) > 0
    code = np.where(yes & ~close & ~ambiguous, TRUE, UNDECIDED)
    return {
        "B": B,
        "C": C,
        "cand": cand,
        "code": code,
        "t": t,
        "between_angle": corridor & ~angled,
        "between_anchor_gap": yes & close,
    }


def between_arrays(
    xy: np.ndarray, uv: np.ndarray, ids: np.ndarray, categories: list[str], dist: np.ndarray, th: Any
) -> Any:
    """between_parts as a tuple (B, C, cand, code, t); None when no pair spans a region."""
    p = between_parts(xy, uv, ids, categories, dist, th)
    return None if p is None else (p["B"], p["C"], p["cand"], p["code"], p["t"])


def between_table(
    xy: np.ndarray, uv: np.ndarray, ids: np.ndarray, categories: list[str], dist: np.ndarray, th: Any
) -> dict[tuple[int, int, int], tuple[int, float]]:
    """{(a, b, c) positions: (code, t)} for anchors b, c with ids[b] < ids[c]; False instances omitted.
    Shared by the geometry and the query index (which passes stored node centres and distances)."""
    return table_from_arrays(between_arrays(xy, uv, ids, categories, dist, th))


def table_from_arrays(arr: Any) -> dict[tuple[int, int, int], tuple[int, float]]:
    """between_table's dict from between_arrays' output (callers holding the arrays skip recomputing them)."""
    if arr is None:
        return {}
    B, C, cand, code, t = arr
    P, A = np.nonzero(cand)
    Bl, Cl = B.tolist(), C.tolist()
    return {
        (a, Bl[p], Cl[p]): (c, tv) for p, a, c, tv in zip(P.tolist(), A.tolist(), code[P, A].tolist(), t[P, A].tolist())
    }


def _between(geom: SceneGeom) -> dict[tuple[int, int, int], tuple[int, float]]:
    return cached(
        geom,
        "contain:between",
        lambda g: between_table(
            g.centers[:, :2], g.img_centroid * (g.W, g.H), g.ids, g.categories, g.surface_distance, g.th
        ),
    )


def _inside_stored(geom: SceneGeom) -> list[RelationFact]:
    frac, codes, m = _inside(geom)
    order = np.argsort(geom.ids, kind="stable")
    return [
        fact("inside", (int(geom.ids[i]), int(geom.ids[j])), codes[i, j], frac[i, j], m)
        for i in order
        for j in order
        if i != j and codes[i, j] != FALSE
    ]


def _inside_eval(negated: bool) -> Callable[..., RelationFact]:
    def evaluate(geom: SceneGeom, a: Any, b: Any) -> RelationFact:
        i, j = pos(geom, a), pos(geom, b)
        frac, codes, m = _inside(geom)
        f = fact("inside", (a, b), codes[i, j], frac[i, j], m)
        if negated:
            return RelationFact("outside", (a, b), None if f.holds is None else not f.holds, f.value, f.margin)
        return f

    return evaluate


def _between_eval(geom: SceneGeom, a: Any, b: Any, c: Any) -> RelationFact:
    i, j, k = pos(geom, a), pos(geom, b), pos(geom, c)
    if geom.ids[j] > geom.ids[k]:
        j, k = k, j
    code, t = _between(geom).get((i, j, k), (FALSE, 0.0))
    return fact("between", (a, b, c), code, t, geom.th.between_t_margin)


_EMPTY_ROW: tuple[frozenset[int], frozenset[int]] = (frozenset(), frozenset())


class BetweenTable:
    """between over a stored graph: the arrays of between_arrays on the stored node centres and distances,
    grouped per anchor pair (b < c): the ids decided between (true) and undecided; every other object is
    False. Single cells read the arrays as lists."""

    def __init__(self, t: RelationTables) -> None:
        self.ids = t.ids
        self.pos = t.pos
        xy = np.array([t.nodes[i].attributes["center"][:2] for i in t.ids], float).reshape(-1, 2)
        W, H = t.graph.meta.get("image_size", (1, 1))
        uv = np.array([t.nodes[i].attributes["img_xy"] for i in t.ids], float).reshape(-1, 2) * (W, H)
        cats = [t.nodes[i].category for i in t.ids]
        arr = between_arrays(xy, uv, np.array(t.ids), cats, t.distance_array(), t.th)
        self.pairs: dict[tuple[int, int], int] = {}
        self.rows: dict[tuple[int, int], tuple[frozenset[int], frozenset[int]]] = {}
        self._cells: tuple[list[list[bool]], list[list[int]], list[list[float]]] = ([], [], [])
        if arr is None:
            return
        B, C, cand, code, tt = arr
        ids = self.ids
        keys = [(ids[b], ids[c]) for b, c in zip(B.tolist(), C.tolist())]
        self.pairs = {k: p for p, k in enumerate(keys)}
        grouped: dict[int, tuple[list[int], list[int]]] = {}
        P, A = np.nonzero(cand)
        for p, a, c in zip(P.tolist(), A.tolist(), code[P, A].tolist()):
            r = grouped.get(p)
            if r is None:
                r = grouped[p] = ([], [])
            r[0 if c == TRUE else 1].append(ids[a])
        for p, (yes, maybe) in grouped.items():
            self.rows[keys[p]] = (frozenset(yes), frozenset(maybe))
        self._cells = (cand.tolist(), code.tolist(), tt.tolist())

    def row(self, b: int, c: int) -> tuple[frozenset[int], frozenset[int]]:
        """(ids decided between b and c, ids undecided) for b < c; most pairs share one empty constant."""
        return self.rows.get((b, c), _EMPTY_ROW)

    @property
    def largest(self) -> int:
        """The most objects decided between any one anchor pair (0 when none)."""
        return max((len(t) for t, _u in self.rows.values()), default=0)

    def code(self, a: int, b: int, c: int) -> tuple[bool | None, float]:
        """(holds, t) of between(a, b, c) for three distinct known ids: an object off the anchor pair's
        candidate mask is False with t = 0 (the rule of between_table)."""
        b, c = int(b), int(c)
        p = self.pairs.get((b, c) if b < c else (c, b))
        if p is None:
            return False, 0.0
        i = self.pos[int(a)]
        cand, code, tt = self._cells
        if not cand[p][i]:
            return False, 0.0
        return holds_of(code[p][i]), tt[p][i]


def _between_table(t: RelationTables) -> BetweenTable | None:
    return None if t.th is None else BetweenTable(t)


def _between_cell(t: RelationTables, args: tuple[Any, ...]) -> Cell | None:
    table = t.table("between")
    if table is None or t.th is None:
        return None
    h, tv = table.code(*args)
    return Cell(h, tv, t.th.between_t_margin)


register(
    Relation(
        "inside",
        "containment",
        "world",
        2,
        "share of A's box volume inside B's box",
        "inside_fraction, inside_band",
        "more than 30% of A's volume lies inside B's box",
        storage="sparse",
        needs=G,
        qa="pairwise",
        evaluate=_inside_eval(False),
        stored=_inside_stored,
        cell=sparse_cell("inside", false_absent(lambda th: th.inside_band)),
        table=sparse_table("inside"),
    )
)
register(
    Relation(
        "outside",
        "containment",
        "world",
        2,
        "share of A's box volume inside B's box",
        "inside_fraction, inside_band",
        "less than 30% of A's volume lies inside B's box",
        storage="derived",
        negation_of="inside",
        needs=G,
        qa="pairwise",
        evaluate=_inside_eval(True),
    )
)
register(
    Relation(
        "between",
        "containment",
        "world",
        3,
        "position of A's centre along the B-C segment (0 at B, 1 at C)",
        "between_t_margin, between_corridor, between_t_band, between_corridor_band, between_max_angle, "
        "between_angle_band, between_anchor_gap",
        "A lies on the segment joining B and C on the ground plane and in the image (well inside its ends, near "
        "its line, within 22 degrees of it seen from each anchor, clear of both anchors), and no other object of "
        "A's category may",
        storage="derived",
        needs=G,
        evaluate=_between_eval,
        cell=_between_cell,
        table=_between_table,
    )
)
