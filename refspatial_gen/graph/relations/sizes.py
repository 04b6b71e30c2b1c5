"""Size comparisons in the gravity frame: tall/short (vertical extent), big/small (box volume),
wide/thin (larger horizontal extent). The margin is relative: the larger must exceed the smaller by
max(absolute, relative x larger), so "taller" is only asked when a person would see it."""

from __future__ import annotations

import numpy as np

from refspatial_gen.core.model import RelationFact
from refspatial_gen.graph.relations.base import Relation, register
from refspatial_gen.graph.relations.common import cached, decide_matrix, pair_evaluator


def compare(q: np.ndarray, abs_margin, rel_margin):
    """(value, codes, margin) matrices for "i larger than j" over quantities q (also used by the query
    index on stored node attributes, so both decide identically). q may stack several quantities on leading
    axes (shape (..., n)), with margins broadcastable to (..., 1, 1): the QA index compares all three sizes
    at once."""
    q = np.asarray(q, float)
    v = q[..., :, None] - q[..., None, :]  # v[i, j] > 0: i larger than j
    m = np.maximum(abs_margin, rel_margin * np.maximum(q[..., :, None], q[..., None, :]))
    return v, decide_matrix(v, m), m


def _tall(geom):
    return cached(geom, "size:tall", lambda g: compare(g.height, g.th.height_margin_abs, g.th.size_margin_rel))


def _big(geom):
    return cached(geom, "size:big", lambda g: compare(g.volume, 0.0, g.th.volume_margin_rel))


def _wide(geom):
    return cached(geom, "size:wide", lambda g: compare(g.width, g.th.width_margin_abs, g.th.size_margin_rel))


# node attribute and thresholds each comparison reads (the query index derives these relations)
DERIVED = {"tall": ("height", "height_margin_abs", "size_margin_rel"), "big": ("volume", None, "volume_margin_rel"),
           "wide": ("width", "width_margin_abs", "size_margin_rel")}


def facts(geom) -> list[RelationFact]:
    """Not stored: derived from node attributes (height, volume, width) by the query index."""
    return []


G = ("gravity",)
register(Relation("tall", "sizes", "world", 2, "vertical extent of A minus B's (m)", "height_margin_abs, size_margin_rel",
                  "A's vertical extent is greater than B's", storage="derived", needs=G, evaluate=pair_evaluator(_tall, "tall")))
register(Relation("short", "sizes", "world", 2, "vertical extent of B minus A's (m)", "height_margin_abs, size_margin_rel",
                  "mirror of tall: A's vertical extent is smaller than B's", mirror_of="tall", storage="derived", needs=G,
                  evaluate=pair_evaluator(_tall, "tall", "short")))
register(Relation("big", "sizes", "world", 2, "box volume of A minus B's (m^3)", "volume_margin_rel",
                  "A's box volume is greater than B's", storage="derived", needs=G, evaluate=pair_evaluator(_big, "big")))
register(Relation("small", "sizes", "world", 2, "box volume of B minus A's (m^3)", "volume_margin_rel",
                  "mirror of big: A's box volume is smaller than B's", mirror_of="big", storage="derived", needs=G,
                  evaluate=pair_evaluator(_big, "big", "small")))
register(Relation("wide", "sizes", "world", 2, "larger horizontal extent of A minus B's (m)", "width_margin_abs, size_margin_rel",
                  "A's larger horizontal extent exceeds B's", storage="derived", needs=G, evaluate=pair_evaluator(_wide, "wide")))
register(Relation("thin", "sizes", "world", 2, "larger horizontal extent of B minus A's (m)", "width_margin_abs, size_margin_rel",
                  "mirror of wide: A's larger horizontal extent is smaller than B's", mirror_of="wide", storage="derived", needs=G,
                  evaluate=pair_evaluator(_wide, "wide", "thin")))
