"""A surface is named in a placement, corner or edge question only when a person can see its top.

Why (audit round 5, ycb sim:000023 #8): "Mark a free place at the far edge of the bottom shelf" named the
floor-level bottom of a dark cabinet seen as a strip a few pixels deep, the same brown as the floor; nobody
could see the shelf, let alone its far edge. Objects have a visibility floor (graph/visibility.py); surfaces
had none.

The seen top face: every pixel's ray is cut with the surface's plane; the pixel shows the top face when the cut
lies inside the surface's outline and the depth map reads the cut's depth (within `visibility_tolerance`).
A surface needs (thresholds, `graph: thresholds:`, lengths for a 640x480 image):

- `min_surface_px` such pixels (scaled by the image area; else `surface_unseen`), and
- a seen top `min_surface_rows` deep: the median, over the image columns that show the top, of the pixels
  each shows (scaled by the image height; else `surface_sliver`);
- the surface of an object below the object floor (graph/visibility.py) is not named either
  (`surface_object_below_floor`).

A surface that fails keeps its place in the scene (objects still stand on it) but gets no corner or edge name
and no free-space region; counts go to graph.meta["truth"]. verify re-measures from the stored depth map by its
own code (qa/verify_surface_seen.py).
"""

from __future__ import annotations

import numpy as np

from refspatial_gen.graph.scene import SceneGeom

UNSEEN = "surface_unseen"
SLIVER = "surface_sliver"
OBJECT_BELOW_FLOOR = "surface_object_below_floor"
REF_W, REF_H = 640, 480


def seen_top(geom: SceneGeom, poly: np.ndarray, z: float) -> np.ndarray:
    """(H, W) bool: the pixels where the depth map shows the plane at height z inside the CCW outline poly."""
    H, W = geom.H, geom.W
    cam = geom.frame.camera
    out = np.zeros((H, W), bool)
    depth = geom.frame.depth
    if depth is None:
        return out
    u, v = np.meshgrid(np.arange(W) + 0.5, np.arange(H) + 0.5)
    rays = np.stack([(u - cam.cx) / cam.fx, (v - cam.cy) / cam.fy, np.ones_like(u)], axis=-1) @ geom.cam_rot_g.T
    o = geom.cam_pos_g
    with np.errstate(divide="ignore", invalid="ignore"):
        t = (z - o[2]) / rays[..., 2]  # camera depth of the cut (rays have unit camera z)
    ok = np.isfinite(t) & (t > 0)
    x = o[0] + np.where(ok, t, 0.0) * rays[..., 0]
    y = o[1] + np.where(ok, t, 0.0) * rays[..., 1]
    for k in range(len(poly)):
        a, b = poly[k], poly[(k + 1) % len(poly)]
        ok &= (b[0] - a[0]) * (y - a[1]) - (b[1] - a[1]) * (x - a[0]) >= 0
    d = np.asarray(depth, float)
    out = ok & (d > 0) & (np.abs(d - np.where(ok, t, 0.0)) <= geom.th.visibility_tolerance)
    return out


def depth_rows(seen: np.ndarray) -> float:
    """Median, over the columns showing any of it, of the seen pixels per column (0 when none)."""
    per_col = seen.sum(axis=0)
    per_col = per_col[per_col > 0]
    return float(np.median(per_col)) if len(per_col) else 0.0


def unseen_why(geom: SceneGeom, object_id: int | None, poly: np.ndarray, z: float) -> str | None:
    """Why a person cannot see this surface's top (a graph.meta["truth"] reason), or None when they can."""
    if object_id is not None:
        idx = np.flatnonzero(geom.ids == object_id)
        if len(idx) and geom.floor_why[int(idx[0])] is not None:
            return OBJECT_BELOW_FLOOR
    if geom.frame.depth is None:
        return None
    seen = seen_top(geom, poly, z)
    th = geom.th
    if seen.sum() < th.min_surface_px * (geom.W * geom.H) / (REF_W * REF_H):
        return UNSEEN
    if depth_rows(seen) < th.min_surface_rows * geom.H / REF_H:
        return SLIVER
    return None
