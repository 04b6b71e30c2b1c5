"""The verifier's own "between": A lies on the segment joining B and C on the ground plane AND in the image.

Why its own code: the generator decides every anchor pair at once on arrays (graph/relations/containment.py);
this recomputes one triple from the stored boxes (gravity-aligned centres) and the decoded masks (pixel
centroids), with the same thresholds and a small tolerance for the graph's rounded attributes, so a bug in
either is caught by the other. A person reads "the cup between the plate and the bowl" as a cup on the line
from the plate to the bowl, well inside its ends; the audit (issue 15) found objects beside both anchors
answered when only a ground-plane corridor was checked.
"""

from __future__ import annotations

import math
from typing import TYPE_CHECKING, Any

import numpy as np

from refspatial_gen.core.geometry import box_distance

if TYPE_CHECKING:
    from refspatial_gen.qa.verify_world import World

# share of |BC|: the generator may decide on the stored graph's rounded attributes (centres to 0.01 mm, image
# centroids to 1e-4); within this of a limit the verifier accepts either side's decision rather than call
# a decided instance undecided. The bands (0.10, 0.15) are far wider, so True and False never meet.
TOL = 2e-3
MIN_SPAN_M = 0.05  # the generator's MIN_BETWEEN_SPAN
MIN_SPAN_PX = 8.0  # the generator's MIN_BETWEEN_PX
# rad: the angular limit's tolerance for the same rounding (1e-4 of the image width moves a centroid 0.06 px;
# seen from an anchor 10 px away that turns the direction by 0.006 rad); the band (0.175) is far wider
ANGLE_TOL = 0.01


def _worst_angle(p: np.ndarray, b: np.ndarray, c: np.ndarray) -> float:
    """The larger of the angles seen from b (towards p vs towards c) and from c (towards p vs towards b),
    from the cosines of the unit directions (the generator takes atan2 of cross and dot products)."""

    def at(o: np.ndarray, q: np.ndarray, r: np.ndarray) -> float:
        u, v = np.asarray(q, float) - o, np.asarray(r, float) - o
        nu, nv = math.hypot(float(u[0]), float(u[1])), math.hypot(float(v[0]), float(v[1]))
        if nu == 0.0 or nv == 0.0:
            return 0.0
        return math.acos(max(-1.0, min(1.0, float(u[0] * v[0] + u[1] * v[1]) / (nu * nv))))

    return max(at(np.asarray(b, float), p, c), at(np.asarray(c, float), p, b))


def _plane(p: np.ndarray, b: np.ndarray, c: np.ndarray, th: Any, min_span: float) -> bool | None:
    """True on the segment and within the angular limit seen from both ends, False clearly off the segment or
    beyond limit + band seen from either end, None in the bands between (each side widened by its tolerance)."""
    bx, by = float(c[0] - b[0]), float(c[1] - b[1])
    span = math.hypot(bx, by)
    if span < min_span:
        return None
    px, py = float(p[0] - b[0]), float(p[1] - b[1])
    t = (px * bx + py * by) / (span * span)
    off = abs(px * by - py * bx) / (span * span)
    m, cor = th.between_t_margin, th.between_corridor
    taper = min(1.0, min(t, 1 - t) / th.between_taper)
    worst = _worst_angle(p, b, c)
    if m - TOL < t < 1 - m + TOL and off < cor * taper + TOL and worst < th.between_max_angle + ANGLE_TOL:
        return True
    lo, hi, wide = m - th.between_t_band, 1 - m + th.between_t_band, cor + th.between_corridor_band
    if t < lo + TOL or t > hi - TOL or off > wide - TOL:
        return False
    if worst > th.between_max_angle + th.between_angle_band - ANGLE_TOL:
        return False
    return None


def _pixel_centre(w: World, oid: int) -> np.ndarray:
    m = w.mask(oid)
    ys, xs = np.nonzero(m)
    if len(xs):
        return np.array([xs.mean() + 0.5, ys.mean() + 0.5])
    cam = w.frame.camera
    uv, _z = cam.project_cam(cam.world_to_cam(w.objects[oid].box.center))
    return np.array([float(uv[0, 0]) + 0.5, float(uv[0, 1]) + 0.5])


def _planes(w: World, a: int, b: int, c: int) -> tuple[bool | None, bool | None]:
    """between(a, b, c) on the ground plane and in the image (each True, False or None)."""
    G, th = w.geom.gravity.rotation, w.geom.th
    ground = {k: (G @ w.objects[k].box.center)[:2] for k in (a, b, c)}
    on_ground = _plane(ground[a], ground[b], ground[c], th, MIN_SPAN_M)
    on_image = _plane(_pixel_centre(w, a), _pixel_centre(w, b), _pixel_centre(w, c), th, MIN_SPAN_PX)
    return on_ground, on_image


def _decide(w: World, a: int, b: int, c: int) -> bool | None:
    """between(a, b, c) in both planes: True when both say so, False when either says clearly not."""
    on_ground, on_image = _planes(w, a, b, c)
    if on_ground is False or on_image is False:
        return False
    if on_ground and on_image:
        return True
    return None


def between_holds(w: World, a: int, b: int, c: int) -> bool | None:
    """between(a, b, c) as a question may ask it: None (undecided) when A is inside a band, lies within
    `between_anchor_gap` x |BC| of an anchor's box (touching included), or another object of A's category is
    not clearly off the segment in both planes ("the cup between ..." must name one cup); False when the
    anchors span no segment on the ground."""
    G = w.geom.gravity.rotation
    gb, gc = ((G @ w.objects[k].box.center)[:2] for k in (b, c))
    span = math.hypot(*(gc - gb))
    if span < MIN_SPAN_M:
        return False
    h = _decide(w, a, b, c)
    if h is not True:
        return h
    ob = w.objects[a].box
    gap = min(box_distance(ob, w.objects[k].box, n=9) for k in (b, c))
    if gap <= 1e-6 or gap < (w.geom.th.between_anchor_gap - TOL) * span:
        return None
    cat = w.objects[a].category
    for k in sorted(w.objects):
        if k not in (a, b, c) and w.objects[k].category == cat and _planes(w, k, b, c) != (False, False):
            return None
    return True
