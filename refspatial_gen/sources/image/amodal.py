"""Amodal completion of a lifted box from its 2D box annotation and gravity (box annotations only).

The depth points of an object give its visible surfaces; the 3D box wanted is the whole object. Two
standard constraints complete it along gravity:
- 2D-3D box consistency (as in Mousavian et al., "3D Bounding Box Estimation Using Deep Learning and
  Geometry"): the projected 3D box must reach the annotated 2D box. When the box's top or bottom row is
  not reached (a mirror, a dark leather headboard or glass without depth), the top (bottom) is raised
  (lowered) until the first corner of the box's top (bottom) face projects onto that row. The smallest
  such extension is taken; an edge on the image border says nothing and is left alone.
- Support completion: objects stand on something: the highest support below the box (a support plane,
  or the top of another object under it: a lamp on a night stand). The bottom is lowered to it only if
  the part added would be hidden, checked against the depth map like a z-buffer: where that part
  projects, the observed depth must be nearer (an occluder: a night stand behind the bed), missing, or
  off the image (a wardrobe cut by the frame). Where the map sees farther than the part (the floor under
  a wall cabinet), the part would be visible and is not there.
"""

from __future__ import annotations

import numpy as np

from refspatial_gen.core.geometry import Box3D


def _z_at_row(corners_xy: np.ndarray, v: float, cam) -> np.ndarray:
    """For each (x, y) world column, the height z whose projection lies on image row `v` (NaN if none)."""
    T = cam.cam_from_world
    R, t = T[:3, :3], T[:3, 3]
    a = np.c_[corners_xy, np.zeros(len(corners_xy))] @ R.T + t  # camera coords at z = 0
    r = R[:, 2]
    dv = v - cam.cy
    den = dv * r[2] - cam.fy * r[1]
    with np.errstate(divide="ignore", invalid="ignore"):
        z = (cam.fy * a[:, 1] - dv * a[:, 2]) / den
    depth = a[:, 2] + z * r[2]
    return np.where(np.isfinite(z) & (depth > 1e-3), z, np.nan)


def _with_z(box: Box3D, bottom: float, top: float) -> Box3D:
    c = box.center.copy()
    s = box.size.copy()
    c[2], s[2] = (bottom + top) / 2, top - bottom
    return Box3D(c, s, box.rotation)


def fit_to_box2d(
    box: Box3D,
    bbox2d: tuple[float, float, float, float],
    cam,
    max_grow: float = 3.0,
    border_px: float = 2.0,
    slack_px: float = 3.0,
) -> tuple[Box3D, dict]:
    """Extend the box along gravity until its projection reaches the 2D box's top and bottom rows."""
    x0, y0, x1, y1 = bbox2d
    notes: dict = {}
    corners = box.corners()
    uv, _ = cam.project(corners)
    if not np.all(np.isfinite(uv)):
        return box, notes
    fp = box.footprint()
    bottom, top = box.bottom_z, box.top_z
    if y0 > border_px and uv[:, 1].min() > y0 + slack_px:
        z = _z_at_row(fp, y0, cam)
        if np.isfinite(z).any():
            zt = float(np.nanmin(z))
            if top < zt <= top + max_grow:
                notes["top_fitted_to_box2d"] = round(zt - top, 4)
                top = zt
    if y1 < cam.height - border_px and uv[:, 1].max() < y1 - slack_px:
        z = _z_at_row(fp, y1, cam)
        if np.isfinite(z).any():
            zb = float(np.nanmax(z))
            if bottom - max_grow <= zb < bottom:
                notes["bottom_fitted_to_box2d"] = round(bottom - zb, 4)
                bottom = zb
    return (_with_z(box, bottom, top) if notes else box), notes


def visible_fraction(
    part: Box3D, depth: np.ndarray, cam, margin_abs: float = 0.10, margin_rel: float = 0.03, n: int = 7
) -> float:
    """Of points spread over `part`'s faces, the fraction the depth map says would be seen: the observed
    depth at their pixel is farther than the point (by a margin). Off-image and no-depth pixels hide."""
    pts = part.surface_points(n)
    uv, z = cam.project(pts)
    H, W = depth.shape
    ok = np.all(np.isfinite(uv), axis=1) & (z > 0)
    u = np.floor(uv[ok, 0]).astype(int)
    v = np.floor(uv[ok, 1]).astype(int)
    z = z[ok]
    inside = (u >= 0) & (u < W) & (v >= 0) & (v < H)
    d = np.zeros(len(z))
    d[inside] = depth[v[inside], u[inside]]
    seen = (d > 0) & (d > z + np.maximum(margin_abs, margin_rel * z))
    return float(seen.sum() / max(len(pts), 1))


def _overlaps(a: Box3D, b: Box3D, slack: float) -> bool:
    """Do the footprints of a and b overlap (within `slack`)? Separating-axis test on the two rectangles."""
    pa, pb = a.footprint(), b.footprint()
    for poly in (pa, pb):
        for k in range(4):
            e = poly[(k + 1) % 4] - poly[k]
            nrm = np.array([-e[1], e[0]])
            if np.linalg.norm(nrm) < 1e-9:
                continue
            nrm /= np.linalg.norm(nrm)
            ra, rb = pa @ nrm, pb @ nrm
            if ra.max() + slack < rb.min() or rb.max() + slack < ra.min():
                return False
    return True


def supports_below(
    box: Box3D,
    footprint_box: Box3D,
    support_z: list[float],
    others: list[tuple[Box3D, Box3D]],
    band: float,
    rest: float = 0.10,
    slack: float = 0.05,
) -> list[float]:
    """Heights the object may stand on: every support plane below its bottom, and the top of every other
    object whose footprint overlaps its own and whose top is below the object's bottom or at most `rest`
    above it (a lamp on a night stand: the stand's top can sit slightly above the lamp's lowest visible
    point). `others`: (box, footprint box) pairs."""
    zs = [z for z in support_z if z < box.bottom_z - band]
    for ob, fb in others:
        if ob.top_z <= box.bottom_z + rest and ob.top_z < box.top_z and _overlaps(footprint_box, fb, slack):
            zs.append(float(ob.top_z))
    return zs


def complete_to_support(
    box: Box3D, depth: np.ndarray, cam, supports: list[float], band: float = 0.03, max_visible: float = 0.1
) -> tuple[Box3D, dict]:
    """Lower the box to the highest support below it when the part added would be hidden in the depth
    map (behind a nearer object, off the image or without depth); see the module docstring."""
    if not supports:
        return box, {}
    z = max(supports)
    if z >= box.bottom_z - band:  # already standing on it
        return box, {}
    part = _with_z(box, z, box.bottom_z)
    seen = visible_fraction(part, depth, cam)
    if seen > max_visible:
        return box, {"support_completion": f"would_be_visible ({seen:.2f})"}
    return _with_z(box, z, box.top_z), {"support_completed": round(box.bottom_z - z, 4)}
