"""The verifier's own world above/below: over B and resting at or above its top, or beside B and clearly higher.

Why its own code: the generator decides every pair at once on arrays (graph/relations/vertical.py and
vertical_clear.py, footprint overlap sampled on a 6x6 grid); this recomputes one pair from the stored boxes
turned into the gravity frame, with the exact footprint intersection (shapely), so a bug in either is
caught by the other. A person reads "the mouse is physically above the tray" as over it or clearly higher:
a mouse on a thin book beside a tray is neither (pre-audit round 5).
"""

from __future__ import annotations

from typing import TYPE_CHECKING

import numpy as np
from shapely.geometry import MultiPoint

if TYPE_CHECKING:
    from refspatial_gen.qa.verify_world import World

TOL = 1e-4  # m: the graph's thresholds are stored rounded; within this of a limit either side's decision stands
# share: the generator samples each footprint on a 6x6 grid, so its overlap share can be off by a sixth (a
# strip); within this of vertical_over_share the verifier accepts "over" (both readings are safe ones), but
# never for disjoint footprints (a sampled point over the other footprint means they do overlap)
OVER_TOL = 1 / 6 + 0.01


def _gravity_box(w: World, oid: int) -> tuple[float, float, float, object]:
    """(bottom, top, centre height, footprint polygon) of an object's box in the gravity frame."""
    corners = w.objects[oid].box.corners() @ np.asarray(w.geom.gravity.rotation, float).T
    z = corners[:, 2]
    return float(z.min()), float(z.max()), float(z.mean()), MultiPoint(corners[:, :2].tolist()).convex_hull


def _overlap_share(pa: object, pb: object) -> float:
    """Intersection area over the smaller footprint's area."""
    small = min(pa.area, pb.area)  # type: ignore[attr-defined]
    return 0.0 if small <= 1e-12 else float(pa.intersection(pb).area / small)  # type: ignore[attr-defined]


def above_world_holds(w: World, a: int, b: int) -> bool | None:
    """above_world(a, b): True (a above b), False (b above a), None (neither clearly: not to be asked)."""
    th = w.geom.th
    tol = th.stack_tolerance
    lo_a, hi_a, c_a, fp_a = _gravity_box(w, a)
    lo_b, hi_b, c_b, fp_b = _gravity_box(w, b)
    if abs(lo_a - lo_b) <= tol - TOL:  # resting on one level: never above/below
        return None
    stacked_ab, stacked_ba = lo_a >= hi_b - tol - TOL, lo_b >= hi_a - tol - TOL
    if stacked_ab and stacked_ba:  # two thin objects side by side at one level
        return None
    if stacked_ab and c_a > c_b:
        side, gap, under_h = True, lo_a - hi_b, hi_b - lo_b
    elif stacked_ba and c_b > c_a:
        side, gap, under_h = False, lo_b - hi_a, hi_a - lo_a
    else:  # heights overlap: side by side, not one above the other
        return None
    share = _overlap_share(fp_a, fp_b)
    if share > 0.0 and share >= th.vertical_over_share - OVER_TOL:
        return side  # over it: resting at or above its top is enough
    need = max(th.vertical_clear_margin, th.vertical_clear_share * under_h)
    return side if gap >= need - TOL else None
