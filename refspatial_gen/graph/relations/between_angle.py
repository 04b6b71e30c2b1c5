"""The angular limit of "between" seen from each anchor, and the gap to the anchors.

Why: a person signs off on "A is between B and C" when, standing at B, A lies roughly towards C, and
standing at C, roughly towards B. The corridor of containment.segment_position is a share of |BC| wide,
so near one anchor it still admitted objects far off the line as seen from that anchor: audit round 4
(sim:000003/v1 #12) found a cereal box ~40 degrees off the bowl-remote line at 20% of the way answered as
"between", and (ycb sim:000009/v0 #6) a spray bottle just beside one anchor. Two rules, applied in the
ground plane and in the image alike:

- seen from B the direction to A must lie within `between_max_angle` (rad) of the direction to C, and
  seen from C within it of the direction to B; more than `between_angle_band` beyond it (either anchor)
  A is clearly not between; in the band it is undecided (counted `between_angle`);
- A's box must be at least `between_anchor_gap` x |BC| (ground plane) from both anchors' boxes: an object
  beside or touching an anchor is not clearly between the two (undecided, counted `between_anchor_gap`).
"""

from __future__ import annotations

from typing import Any

import numpy as np

Array = np.ndarray[Any, Any]


def anchor_angles(xy: Array, B: Array, C: Array) -> tuple[Array, Array]:
    """(at_b, at_c), each (pairs, objects): the angle at anchor B[p] between the directions to object a and
    to C[p], and at C[p] between the directions to a and to B[p] (rad, 0..pi; 0 for an object at the anchor)."""
    seg = xy[C] - xy[B]

    def at(origin: Array, towards: Array) -> Array:
        rel = xy[None, :, :] - origin[:, None, :]
        dot = rel[..., 0] * towards[:, None, 0] + rel[..., 1] * towards[:, None, 1]
        cross = rel[..., 0] * towards[:, None, 1] - rel[..., 1] * towards[:, None, 0]
        return np.arctan2(np.abs(cross), dot)

    return at(xy[B], seg), at(xy[C], -seg)


def angle_masks(xy: Array, B: Array, C: Array, th: Any) -> tuple[Array, Array]:
    """(within, outside) per (pair, object): within the angular limit seen from both anchors, or clearly
    outside it (beyond limit + band) seen from either; neither is the undecided band."""
    at_b, at_c = anchor_angles(xy, B, C)
    worst = np.maximum(at_b, at_c)
    return worst < th.between_max_angle, worst > th.between_max_angle + th.between_angle_band


def near_anchor(dist: Array, B: Array, C: Array, span: Array, th: Any) -> Array:
    """(pairs, objects): True where the object's box lies within `between_anchor_gap` x |BC| of either anchor's
    box (`dist` the surface distances, `span` the ground-plane |BC| of each pair), touching included."""
    gap = np.minimum(dist[:, B].T, dist[:, C].T)
    return (gap <= 1e-6) | (gap < th.between_anchor_gap * span[:, None])


def count_between(geom: Any) -> None:
    """graph.meta["truth"]: between instances (object, unordered anchor pair) on the corridor in both planes
    that the angular limit (`between_angle`) or, within it, the anchor gap (`between_anchor_gap`) withholds."""
    if not geom.world_ok:
        return
    from refspatial_gen.graph.relations.containment import between_parts

    parts = between_parts(
        geom.centers[:, :2],
        geom.img_centroid * (geom.W, geom.H),
        geom.ids,
        geom.categories,
        geom.surface_distance,
        geom.th,
    )
    if parts is None:
        return
    truth = geom.cache.setdefault("truth", {})
    for reason in ("between_angle", "between_anchor_gap"):
        n = int(np.count_nonzero(parts[reason]))
        if n:
            truth[reason] = truth.get(reason, 0) + n
