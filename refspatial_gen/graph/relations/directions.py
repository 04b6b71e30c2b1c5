"""Viewer-centred directions: left/right and front/behind (camera frame), above/below in the image.

Why these rules: "left" is judged on 3D centres in the camera frame (RefSpatial), but a person checks it
in the image; when perspective makes the two disagree the relation is left undecided rather than asked.
"Front" uses nearest-face depth, and is undecided when centre depths order the objects the other way.
Both are undecided when the two boxes overlap: footprints intersecting and extents along the axis asked
sharing more than half the shorter one (camera x for left/right,
depth for front/behind): a cup on the right half of a table is not "right of the table", nor is a cup
standing on it "behind" the table's front edge.
"""

from __future__ import annotations

from collections.abc import Callable

import numpy as np

from refspatial_gen.core.model import RelationFact
from refspatial_gen.graph.relations.base import Relation, register
from refspatial_gen.graph.relations.common import (
    UNDECIDED,
    Matrices,
    cached,
    count,
    decide_matrix,
    pair_evaluator,
    pair_facts,
)
from refspatial_gen.graph.relations.lookup import pair_cell, pair_table
from refspatial_gen.graph.relations.span import span_contains
from refspatial_gen.graph.scene import SceneGeom

OVERLAP_SHARE = 0.5  # extents sharing more than this share of the shorter one along the axis: undecided


def overlapping(geom: SceneGeom, axis: int) -> np.ndarray:
    """[i, j]: the two boxes overlap: their ground footprints intersect (one stands on or in the other) and
    their extents along camera axis `axis` (0 x, 2 depth) share more than OVERLAP_SHARE of the shorter one.
    Neighbours with disjoint footprints stay decided however perspective stretches their extents."""
    lo, hi = geom.cam_lo[:, axis], geom.cam_hi[:, axis]
    common = np.minimum(hi[:, None], hi[None, :]) - np.maximum(lo[:, None], lo[None, :])
    ext = hi - lo
    fp = geom.footprint_overlap
    return (common > OVERLAP_SHARE * np.minimum(ext[:, None], ext[None, :])) & (np.maximum(fp, fp.T) > 0)


def image_gap(geom: SceneGeom, axis: int, floor: float) -> np.ndarray:
    """[i, j]: the separation the two image centroids need along image `axis` (0 x, 1 y) for a person to see
    the order: `image_extent_share` of the smaller of the two masks' extents along the axis and, where the
    extents overlap (one object in front of the other), at least `floor` (a fraction of the image side).
    Masks side by side (disjoint extents) show their order however small they are; an object without a
    mask needs the floor."""
    span = geom.img_cols if axis == 0 else geom.img_rows
    lo, hi = span[:, 0], span[:, 1]
    with np.errstate(invalid="ignore"):
        smaller = np.fmin((hi - lo)[:, None], (hi - lo)[None, :])
        apart = (np.minimum(hi[:, None], hi[None, :]) - np.maximum(lo[:, None], lo[None, :])) <= 0
        need = np.where(apart, 0.0, floor)  # NaN extents compare False: not apart, the floor applies
        return np.fmax(need, geom.th.image_extent_share * smaller)


def _lateral(geom: SceneGeom) -> Matrices:
    """Camera-frame centres decide with the metric margin; the image must agree and show the order clearly:
    centroids apart by image_extent_share of the narrower mask and, where the masks' columns overlap, by
    image_clear_margin of the width (a tray lying in front of two others and overlapping both is neither left
    nor right of them; a box 2% of the width left of the box behind it is not "left of" it: audit round 2);
    neither mask reaching image_span_margin past both ends of the other (graph/relations/span.py)."""
    x = geom.cam_centers[:, 0]
    u = geom.img_centroid[:, 0]
    v = x[None, :] - x[:, None]  # v[i, j] > 0: i is left of j
    du = u[None, :] - u[:, None]
    codes = decide_matrix(v, geom.th.lateral_margin)
    disagree = (np.sign(du) != np.sign(v)) | (np.abs(du) < 0.5 * geom.th.image_margin)
    codes[disagree | overlapping(geom, 0)] = UNDECIDED
    unclear = (codes != UNDECIDED) & (np.abs(du) < image_gap(geom, 0, geom.th.image_clear_margin))
    count(geom, "margin_image_lateral", unclear)
    codes[unclear] = UNDECIDED
    spanned = (codes != UNDECIDED) & span_contains(geom, 0)
    count(geom, "image_span_contains", spanned)
    codes[spanned] = UNDECIDED
    return v, codes, geom.th.lateral_margin


def _depthwise(geom: SceneGeom) -> Matrices:
    """Nearest-face depths decide with depth_margin and, on top, a relative margin: the farther face at least
    depth_margin_rel beyond the nearer (two bicycles at 9.8 and 10.0 m are not one "nearer": audit round 2)."""
    d = geom.near_depth
    v = d[None, :] - d[:, None]  # v[i, j] > 0: i nearer than j
    c = geom.center_depth
    vc = c[None, :] - c[:, None]
    m = np.maximum(geom.th.depth_margin, geom.th.depth_margin_rel * np.maximum(np.abs(d[:, None]), np.abs(d[None, :])))
    codes = decide_matrix(v, geom.th.depth_margin)
    codes[(np.sign(vc) != np.sign(v)) | overlapping(geom, 2)] = UNDECIDED
    unclear = (codes != UNDECIDED) & (np.abs(v) <= m)
    count(geom, "margin_depth_relative", unclear)
    codes[unclear] = UNDECIDED
    return v, codes, m


def _image_vertical(geom: SceneGeom) -> Matrices:
    """Mask centroids decide, but only where the masks' top rows and bottom rows order the two objects the same
    way: a person and a refrigerator spanning the same rows are not one "higher in the image" than the other
    because the person's mass sits in a skirt (audit round 2). This already leaves a mask spanning the other's
    rows undecided (its top is higher, its bottom lower), with any margin: the row form of span_contains."""
    y = geom.img_centroid[:, 1]
    v = y[None, :] - y[:, None]  # v[i, j] > 0: i higher in the image than j
    codes = decide_matrix(v, geom.th.image_margin)
    top, bottom = geom.img_rows[:, 0], geom.img_rows[:, 1]
    with np.errstate(invalid="ignore"):
        dt = top[None, :] - top[:, None]
        db = bottom[None, :] - bottom[:, None]
        known = np.isfinite(dt) & np.isfinite(db)
        codes[known & ((np.sign(dt) != np.sign(v)) | (np.sign(db) != np.sign(v)))] = UNDECIDED
    unclear = (codes != UNDECIDED) & (np.abs(v) < image_gap(geom, 1, geom.th.image_clear_margin))
    count(geom, "margin_image_vertical", unclear)
    codes[unclear] = UNDECIDED
    return v, codes, geom.th.image_margin


_GROUPS = {"left": _lateral, "front": _depthwise, "above_image": _image_vertical}


def matrices(geom: SceneGeom, rel: str) -> Matrices:
    return cached(geom, "dir:" + rel, _GROUPS[rel])


def _m(rel: str) -> Callable[[SceneGeom], Matrices]:
    return lambda geom: matrices(geom, rel)


def _stored(rel: str) -> Callable[[SceneGeom], list[RelationFact]]:
    return lambda geom: pair_facts(rel, geom, *matrices(geom, rel))


def _pair(rid: str, frame: str, value: str, margin: str, definition: str) -> None:
    """A canonical pair relation: stored once per pair, looked up and tabled by the pair rules."""
    register(
        Relation(
            rid,
            "directions",
            frame,
            2,
            value,
            margin,
            definition,
            qa="ordered",
            evaluate=pair_evaluator(_m(rid), rid),
            stored=_stored(rid),
            cell=pair_cell(rid),
            table=pair_table(rid),
        )
    )


def _mirror(rid: str, of: str, frame: str, value: str, margin: str, definition: str) -> None:
    register(
        Relation(
            rid,
            "directions",
            frame,
            2,
            value,
            margin,
            definition,
            mirror_of=of,
            qa="ordered",
            evaluate=pair_evaluator(_m(of), of, rid),
        )
    )


_pair(
    "left",
    "cam",
    "camera-x of B's centre minus A's (m)",
    "lateral_margin, image_margin, image_clear_margin, image_extent_share, image_span_margin",
    "A's centre is left of B's in the camera frame by more than the margin, the image agrees with the mask "
    "centroids clearly apart (image_extent_share of the narrower mask, and image_clear_margin of the width "
    "where the masks' columns overlap), neither mask reaching image_span_margin of the width past both ends of "
    "the other, and their boxes do not overlap (footprints, half the shorter x extent)",
)
_mirror(
    "right",
    "left",
    "cam",
    "camera-x of A's centre minus B's (m)",
    "lateral_margin, image_margin, image_clear_margin, image_extent_share, image_span_margin",
    "mirror of left: A's centre is right of B's",
)
_pair(
    "front",
    "cam",
    "nearest-face depth of B minus A's (m)",
    "depth_margin, depth_margin_rel",
    "A's nearest face is nearer the camera than B's by the margin and by depth_margin_rel of the farther "
    "(centre depths agree, boxes do not overlap (footprints, half the shorter depth extent))",
)
_mirror(
    "behind",
    "front",
    "cam",
    "nearest-face depth of A minus B's (m)",
    "depth_margin, depth_margin_rel",
    "mirror of front: A is farther from the camera than B",
)
_pair(
    "above_image",
    "img",
    "image-y of B's mask centroid minus A's (fraction of height)",
    "image_margin, image_clear_margin, image_extent_share",
    "A's 2D centre is higher in the image than B's by image_extent_share of the shorter mask (and "
    "image_clear_margin of the height where the masks' rows overlap), "
    "the masks' top and bottom rows agreeing",
)
_mirror(
    "below_image",
    "above_image",
    "img",
    "image-y of A's mask centroid minus B's (fraction of height)",
    "image_margin, image_clear_margin, image_extent_share",
    "mirror of above (image): A's 2D centre is lower in the image",
)
