"""verify's own re-check of a box-only scan object's answer pixel (the source's rule: sources/scan/surface.py).

Why its own code: a box's mask on a scan without instance labels holds whatever stands inside the box (the
TV in a cabinet's niche, audit round 3); the source withholds an answer point lying more than the frame's
`max_point_recess` behind where the pixel's ray enters the box. verify recomputes that distance from the
stored depth map, camera, box and mask (slab test on the ray through the pixel centre, median known depth
of the object's pixels in a 5x5 window), sharing no code with the source.
"""

from __future__ import annotations

from typing import Any

import numpy as np


def _entry_z(frame: Any, box: Any, x: int, y: int) -> float:
    """Camera z where the ray through pixel (x, y) enters the box (0 from inside), inf when it misses."""
    cam = frame.camera
    d_cam = np.array([(x + 0.5 - cam.cx) / cam.fx, (y + 0.5 - cam.cy) / cam.fy, 1.0])
    pose = np.asarray(cam.world_from_cam, float)
    axes = np.asarray(box.rotation, float)  # columns: the box's axes in the world
    d = axes.T @ (pose[:3, :3] @ d_cam)
    o = axes.T @ (pose[:3, 3] - np.asarray(box.center, float))
    h = np.asarray(box.size, float) / 2.0
    lo, hi = 0.0, np.inf
    for k in range(3):
        if abs(d[k]) < 1e-12:
            if abs(o[k]) > h[k]:
                return float("inf")
            continue
        a, b = sorted(((-h[k] - o[k]) / d[k], (h[k] - o[k]) / d[k]))
        lo, hi = max(lo, a), min(hi, b)
    return float(lo) if lo <= hi else float("inf")


def _box_only(o: Any) -> bool:
    p = o.provenance or {}
    return p.get("source") == "scan" and "instance" not in p and not p.get("distractor_only") and o.mask is not None


def check_recess(frame: Any, oid: int, x: int, y: int) -> list[str]:
    """Problems with an answer pixel on a box-only scan object (empty when the frame records no limit)."""
    limit = (frame.meta or {}).get("max_point_recess")
    o = next((o for o in frame.objects if o.id == oid), None)
    if limit is None or o is None or frame.depth is None or not _box_only(o):
        return []
    depth = np.asarray(frame.depth, np.float64)
    mask = o.mask.decode()
    ys, xs = slice(max(0, y - 2), y + 3), slice(max(0, x - 2), x + 3)
    known = depth[ys, xs][mask[ys, xs] & (depth[ys, xs] > 0)]
    z = _entry_z(frame, o.box, x, y)
    if known.size == 0 or not np.isfinite(z):
        return []
    r = float(np.median(known)) - z
    if r <= float(limit):
        return []
    return [f"answer pixel {x},{y} lies {r:.2f} m behind the entry face of object {oid}'s box (> {limit})"]
