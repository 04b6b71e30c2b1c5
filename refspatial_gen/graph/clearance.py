"""Clearance of free-space answer points (graph/freespace.py): a point a person would call free keeps away from
every object it could be read as touching, in the image and on the surface.

Why: audit round 2, a point "behind the mug" touched the mug in the image; round 1, points against a tray rim
and an unlabelled chair base. Thresholds: `graph: truth: min_point_clearance_px` (graph/visibility.py, px at
640x480, scaled) and the thresholds' `free_clearance` (m). verify re-checks both (qa/verify_truth.py).
"""

from __future__ import annotations

import numpy as np
import shapely
from shapely.ops import unary_union

from refspatial_gen.graph.scene import SceneGeom
from refspatial_gen.graph.visibility import Floor, px_scale


def clearance_map(geom: SceneGeom, exclude: int | None) -> np.ndarray:
    """(H, W) distance in pixels from each pixel to the nearest mask pixel of any object but `exclude` (the
    surface's own object, which the point lies on); inf everywhere when there is no such mask."""
    key = f"_clearance_map:{exclude}"
    hit = geom.cache.get(key)
    if hit is None:
        import cv2

        occupied = np.zeros((geom.H, geom.W), bool)
        for o in geom.frame.objects:
            if o.id != exclude and o.mask is not None and o.mask.area:
                occupied |= o.mask.decode()
        if occupied.any():
            hit = cv2.distanceTransform((~occupied).astype(np.uint8), cv2.DIST_L2, cv2.DIST_MASK_PRECISE)
        else:
            hit = np.full((geom.H, geom.W), np.inf, np.float32)
        geom.cache[key] = hit
    return hit


def clear_samples(
    geom: SceneGeom, uv: np.ndarray, xy: np.ndarray, exclude: int | None, obstacles: list[np.ndarray]
) -> np.ndarray:
    """Which pixels `uv` (n, 2 ints) with plane points `xy` (n, 2) keep the clearance: from the image border and
    every object's mask but `exclude` (`min_point_clearance_px`, scaled to the image), and in the plane from
    every obstacle footprint (`free_clearance`)."""
    floor = geom.cache.get("floor") or Floor()
    c = floor.min_point_clearance_px * px_scale(geom.W, geom.H)
    u, v = uv[:, 0], uv[:, 1]
    ok = (u >= c) & (v >= c) & (geom.W - 1 - u >= c) & (geom.H - 1 - v >= c)
    idx = np.flatnonzero(ok)
    ok[idx] = clearance_map(geom, exclude)[v[idx], u[idx]] >= c
    if obstacles and ok.any():
        idx = np.flatnonzero(ok)
        blocked = unary_union(list(shapely.polygons(np.asarray(obstacles, float))))
        d = shapely.distance(shapely.points(xy[idx]), blocked)
        ok[idx] = d >= geom.th.free_clearance - 1e-9
    return ok
