"""Corner and edge names of a support surface only where a person sees that corner or edge, at the top face's
real extent.

Why (audit round 4): a free-space "far-right corner" of a bed was taken where the declared surface stopped while
the mattress visibly went on 0.3 m to the headboard; "is the bed near the near-left corner of the floor?" was
asked on a scan whose floor is a slab around the camera, with only a sliver of floor in the picture. Two rules,
both read off the depth map (thresholds: `graph: thresholds:`, graph/constants.py):

- extent (`surface_extent_continues`): the surface's plane is sampled in a band `extent_band` wide just outside
  each side of its outline; when the depth map shows the plane (within `visibility_tolerance` in depth and
  `extent_height_tolerance` in height) on more than
  `max_extent_continuation` of the band's samples it sees, the top face goes on past that side: the side's
  edge name and the names of its two corners are withheld.
- seen (`corner_unseen`, `edge_unseen`): a corner's square (side max(corner_size, corner_reach + band margin))
  and an edge's band (width max(edge_width, edge_band + band margin)) are sampled on the surface; a sample is
  shown when the depth map sees the plane there, or it lies under an object standing on the surface (its
  bounding footprint at most twice the corner square) that the pixel shows in front of it. Samples outside
  the image count as not shown. A corner (edge) needs
  `min_corner_seen` (`min_edge_seen`) of its samples shown, else its name is withheld.

Withheld names are never asked (no corner/edge relation instance, no corner/edge free-space region); counts go
to graph.meta["truth"]. verify re-checks both rules by its own code (qa/verify_corners.py).
"""

from __future__ import annotations

from typing import Any

import numpy as np

from refspatial_gen.graph.scene import SceneGeom, points_in_polygons

EXTENT = "surface_extent_continues"
CORNER_UNSEEN = "corner_unseen"
EDGE_UNSEEN = "edge_unseen"
GRID = 12  # samples per side of a corner square / along and across an edge band
MIN_BAND_SEEN = 6  # band samples with a depth reading needed before the extent rule can say anything


def _count(geom: SceneGeom, reason: str, n: int = 1) -> None:
    truth = geom.cache.setdefault("truth", {})
    truth[reason] = truth.get(reason, 0) + n


def _lattice(origin: np.ndarray, e1: np.ndarray, e2: np.ndarray, n1: int, n2: int) -> np.ndarray:
    """Cell centres of the parallelogram origin + [0,1] e1 + [0,1] e2 ((n1 * n2, 2))."""
    s = (np.arange(n1) + 0.5) / n1
    t = (np.arange(n2) + 0.5) / n2
    u, v = np.meshgrid(s, t, indexing="ij")
    return origin + u.reshape(-1, 1) * e1 + v.reshape(-1, 1) * e2


def _look(geom: SceneGeom, pts: np.ndarray, z: float) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Per sample: (camera depth of the plane point, depth map reading or 0, in the image and in front)."""
    uv, zc = geom.project_world(np.column_stack([pts, np.full(len(pts), z)]))
    ok = np.isfinite(uv).all(axis=1) & (zc > 0)
    u = np.floor(np.where(ok, uv[:, 0], -1)).astype(int)
    v = np.floor(np.where(ok, uv[:, 1], -1)).astype(int)
    ok &= (u >= 0) & (u < geom.W) & (v >= 0) & (v < geom.H)
    d = np.zeros(len(pts))
    d[ok] = np.asarray(geom.frame.depth)[v[ok], u[ok]]
    return zc, d, ok


def shown_share(geom: SceneGeom, pts: np.ndarray, z: float, under: list[np.ndarray]) -> float:
    """Share of the samples where the picture shows the surface: the plane itself, or an object standing there."""
    if not len(pts):
        return 0.0
    zc, d, ok = _look(geom, pts, z)
    tol = geom.th.visibility_tolerance
    shown = ok & (d > 0) & (np.abs(d - zc) <= tol)
    if under:
        inside = points_in_polygons(pts, np.asarray(under, float)).any(axis=0)  # (polygons, points)
        shown |= ok & (d > 0) & (d < zc + tol) & inside
    return float(shown.mean())


def continuation_share(geom: SceneGeom, a: np.ndarray, b: np.ndarray, z: float) -> float:
    """Share of the seen samples just outside side a->b (of a CCW outline) where the depth map shows the plane."""
    e = b - a
    out = np.array([e[1], -e[0]]) / (np.linalg.norm(e) + 1e-12)
    band = geom.th.extent_band
    pts = _lattice(a + out * band * 0.2, e, out * band * 0.8, GRID, 4)
    zc, d, ok = _look(geom, pts, z)
    seen = ok & (d > 0)
    if seen.sum() < MIN_BAND_SEEN:
        return 0.0
    # the height of what the pixel shows above the plane: the depth ratio scales the plane point's ray (a step
    # of a book's thickness stays within the depth tolerance at a grazing view, not within this)
    rise = abs(float(geom.cam_pos_g[2]) - z) * np.abs(d - zc) / np.maximum(zc, 1e-9)
    flat = (np.abs(d - zc) <= geom.th.visibility_tolerance) & (rise <= geom.th.extent_height_tolerance)
    return float((seen & flat).sum() / seen.sum())


def _standing(geom: SceneGeom, z: float, side: float) -> list[np.ndarray]:
    """Footprints of the objects standing on the plane at height z (bottom within support_gap) at most twice a
    corner square: a cup at a table's corner shows where the corner is, a bed over a floor corner hides it."""
    area = (geom.hi[:, 0] - geom.lo[:, 0]) * (geom.hi[:, 1] - geom.lo[:, 1])
    keep = (np.abs(geom.lo[:, 2] - z) <= geom.th.support_gap) & (geom.hi[:, 2] > z) & (area <= 2.0 * side * side)
    return [geom.footprints[i] for i in np.flatnonzero(keep)]


def corner_square(poly: np.ndarray, k: int, side: float) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """(corner, e1, e2) of the square at vertex k, its sides along the outline, at most half each side long."""
    p = poly[k]
    e1, e2 = poly[(k + 1) % 4] - p, poly[(k - 1) % 4] - p
    e1 = e1 / np.linalg.norm(e1) * min(side, np.linalg.norm(e1) / 2)
    e2 = e2 / np.linalg.norm(e2) * min(side, np.linalg.norm(e2) / 2)
    return p, e1, e2


def edge_band(a: np.ndarray, b: np.ndarray, width: float) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """(a, along, inward) of the band along side a->b of a CCW outline, at most half the side long inwards."""
    e = b - a
    inward = np.array([-e[1], e[0]]) / (np.linalg.norm(e) + 1e-12)
    return a, e, inward * min(width, float(np.linalg.norm(e)) / 2)


def filter_seen(geom: SceneGeom, entry: dict[str, Any]) -> None:
    """Withhold the corner and edge names of one surface entry (surface_labels) a person could not see there."""
    corners, edges = entry["corners"], entry["edges"]
    if (not corners and not edges) or geom.frame.depth is None:
        return
    th, poly, z = geom.th, entry["polygon"], float(entry["z"])
    vertex = {name: int(np.argmin(np.linalg.norm(poly - p, axis=1))) for name, p in corners.items()}
    side_of = {name: int(np.argmin([np.linalg.norm(poly[k] - a) for k in range(4)])) for name, (a, _b) in edges.items()}
    for k in range(4):
        if continuation_share(geom, poly[k], poly[(k + 1) % 4], z) > th.max_extent_continuation:
            for name in [n for n, v in vertex.items() if v in (k, (k + 1) % 4) and n in corners]:
                del corners[name]
                _count(geom, EXTENT)
            for name in [n for n, s in side_of.items() if s == k and n in edges]:
                del edges[name]
                _count(geom, EXTENT)
    side = max(th.corner_size, th.corner_reach + th.surface_band_margin)
    under = _standing(geom, z, side)
    for name in sorted(corners):
        p, e1, e2 = corner_square(poly, vertex[name], side)
        if shown_share(geom, _lattice(p, e1, e2, GRID, GRID), z, under) < th.min_corner_seen:
            del corners[name]
            _count(geom, CORNER_UNSEEN)
    width = max(th.edge_width, th.edge_band + th.surface_band_margin)
    for name in sorted(edges):
        a, b = edges[name]
        o, along, inward = edge_band(a, b, width)
        if shown_share(geom, _lattice(o, along, inward, 3 * GRID, 4), z, under) < th.min_edge_seen:
            del edges[name]
            _count(geom, EDGE_UNSEEN)
