"""Size comparisons in the gravity frame: tall/short (vertical extent), big/small (box volume),
wide/thin (larger horizontal extent). The margin is relative: the larger must exceed the smaller by
max(absolute, relative x larger), so "taller" is only asked when a person would see it."""

from __future__ import annotations

from collections.abc import Callable
from typing import TYPE_CHECKING, Any

import numpy as np

from refspatial_gen.core.model import RelationFact
from refspatial_gen.graph.relations.base import HOLDS_OF_CODE, T_MISSING, Cell, CellRule, Relation, Rows, register
from refspatial_gen.graph.relations.common import Matrices, cached, count, decide_matrix, pair_evaluator
from refspatial_gen.graph.scene import SceneGeom

if TYPE_CHECKING:
    from refspatial_gen.graph.tables import RelationTables


def compare(q: Any, abs_margin: Any, rel_margin: Any) -> Matrices:
    """(value, codes, margin) matrices for "i larger than j" over quantities q (also used by the query
    index on stored node attributes, so both decide identically). q may stack several quantities on leading
    axes (shape (..., n)), with margins broadcastable to (..., 1, 1): the QA index compares all three sizes
    at once."""
    q = np.asarray(q, float)
    v = q[..., :, None] - q[..., None, :]  # v[i, j] > 0: i larger than j
    m = np.maximum(abs_margin, rel_margin * np.maximum(q[..., :, None], q[..., None, :]))
    return v, decide_matrix(v, m), m


def _tall(geom: SceneGeom) -> Matrices:
    return cached(geom, "size:tall", lambda g: compare(g.height, g.th.height_margin_abs, g.th.size_margin_rel))


def _big(geom: SceneGeom) -> Matrices:
    return cached(geom, "size:big", lambda g: compare(g.volume, 0.0, g.th.volume_margin_rel))


def _wide(geom: SceneGeom) -> Matrices:
    return cached(geom, "size:wide", lambda g: compare(g.width, g.th.width_margin_abs, g.th.size_margin_rel))


def _count_relative(geom: SceneGeom) -> list[RelationFact]:
    """Stores nothing (sizes are derived from node attributes); counts in graph.meta["truth"] the pairs whose
    difference clears the absolute margin but not the relative one (`size_undecided_ratio`: the larger is
    not size_margin_rel / volume_margin_rel bigger, so no size word is given: audit round 2, four wine
    glasses of about the same height, one called "the tallest")."""
    th = geom.th
    for q, absm, relm in (
        (geom.height, th.height_margin_abs, th.size_margin_rel),
        (geom.volume, 0.0, th.volume_margin_rel),
        (geom.width, th.width_margin_abs, th.size_margin_rel),
    ):
        v = np.abs(q[:, None] - q[None, :])
        count(geom, "size_undecided_ratio", (v > absm) & (v <= relm * np.maximum(q[:, None], q[None, :])))
    return []


# node attribute and thresholds each comparison reads (a stored graph derives these relations from them)
DERIVED = {
    "tall": ("height", "height_margin_abs", "size_margin_rel"),
    "big": ("volume", None, "volume_margin_rel"),
    "wide": ("width", "width_margin_abs", "size_margin_rel"),
}


def _size_tables(t: RelationTables) -> dict[str, tuple[Rows, list[list[float]], list[list[float]]]] | None:
    """{base: (code rows, value rows, margin rows)} over t.ids for tall, big and wide, with the builder's own
    decision function on the stored node attributes, the three quantities stacked (one set of array
    operations instead of three). None without thresholds or objects."""
    th, ids = t.th, t.ids
    if th is None or not ids:
        return None
    bases = list(DERIVED)
    q = np.array([[t.nodes[i].attributes[DERIVED[b][0]] for i in ids] for b in bases], float)
    absm = np.array([getattr(th, a) if a else 0.0 for _, a, _ in DERIVED.values()])[:, None, None]
    relm = np.array([getattr(th, r) for _, _, r in DERIVED.values()])[:, None, None]
    v, codes, m = compare(q, absm, relm)
    # builder codes TRUE 1 / FALSE 0 / UNDECIDED -1 -> table codes 1 / 0 / 2 (floor modulo 3)
    ours = np.mod(np.asarray(codes, dtype=np.int8), 3)
    n = len(ids)
    ours[:, np.arange(n), np.arange(n)] = T_MISSING
    rows, vals, margins = ours.tolist(), v.tolist(), np.broadcast_to(m, v.shape).tolist()  # python values
    return {b: (rows[k], vals[k], margins[k]) for k, b in enumerate(bases)}


def _table(base: str) -> Callable[[RelationTables], Rows | None]:
    def table(t: RelationTables) -> Rows | None:
        tabs = t.shared("sizes", _size_tables)
        return None if tabs is None else tabs[base][0]

    return table


def _cell(base: str) -> CellRule:
    def cell(t: RelationTables, args: tuple[Any, ...]) -> Cell | None:
        tabs = t.shared("sizes", _size_tables)
        if tabs is None:
            return None
        codes, vals, margins = tabs[base]
        i, j = t.pos[args[0]], t.pos[args[1]]
        return Cell(HOLDS_OF_CODE[codes[i][j]], vals[i][j], margins[i][j])

    return cell


G = ("gravity",)


def _size(rid: str, value: str, margin: str, definition: str) -> None:
    register(
        Relation(
            rid,
            "sizes",
            "world",
            2,
            value,
            margin,
            definition,
            storage="derived",
            needs=G,
            qa="ordered",
            key_step="Size",
            evaluate=pair_evaluator(_MATRICES[rid], rid),
            stored=_count_relative if rid == "tall" else None,
            cell=_cell(rid),
            table=_table(rid),
        )
    )


def _mirror(rid: str, of: str, value: str, margin: str, definition: str) -> None:
    register(
        Relation(
            rid,
            "sizes",
            "world",
            2,
            value,
            margin,
            definition,
            mirror_of=of,
            storage="derived",
            needs=G,
            qa="ordered",
            key_step="Size",
            evaluate=pair_evaluator(_MATRICES[of], of, rid),
        )
    )


_MATRICES = {"tall": _tall, "big": _big, "wide": _wide}
_size(
    "tall",
    "vertical extent of A minus B's (m)",
    "height_margin_abs, size_margin_rel",
    "A's vertical extent is greater than B's",
)
_mirror(
    "short",
    "tall",
    "vertical extent of B minus A's (m)",
    "height_margin_abs, size_margin_rel",
    "mirror of tall: A's vertical extent is smaller than B's",
)
_size("big", "box volume of A minus B's (m^3)", "volume_margin_rel", "A's box volume is greater than B's")
_mirror(
    "small",
    "big",
    "box volume of B minus A's (m^3)",
    "volume_margin_rel",
    "mirror of big: A's box volume is smaller than B's",
)
_size(
    "wide",
    "larger horizontal extent of A minus B's (m)",
    "width_margin_abs, size_margin_rel",
    "A's larger horizontal extent exceeds B's",
)
_mirror(
    "thin",
    "wide",
    "larger horizontal extent of B minus A's (m)",
    "width_margin_abs, size_margin_rel",
    "mirror of wide: A's larger horizontal extent is smaller than B's",
)
