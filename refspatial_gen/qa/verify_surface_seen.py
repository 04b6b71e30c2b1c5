"""verify's own re-check that a surface a pair names (a free-space region on it, one of its corners or edges) is
one a person can see the top of (the generator's rule: graph/surface_visible.py).

Why its own code: the generator cuts every pixel's ray with the surface's plane and compares the cut's depth
with the depth map. verify goes the other way: it lifts every depth-map pixel to a 3D point (pinhole model,
stored camera and gravity), keeps the points on the plane (their height off it within the depth tolerance
carried along the ray) inside the top face it rebuilds from the stored box, and counts them per image column.
Counts are compared with `SLACK` for the differing boundary pixels. A surface of an object under the recorded
object floor is re-decided by verify's own floor (qa/verify_truth.py).
"""

from __future__ import annotations

from typing import Any

import numpy as np

SLACK = 0.1  # share by which verify's pixel count / depth may fall short of the generator's threshold
REF_W, REF_H = 640, 480


def named_surfaces(qa: Any) -> list[str]:
    """Surface ids a pair's program names: free-space regions (any kind) and corner/edge spots."""
    out: list[str] = []
    for st in qa.program or []:
        args = st.get("args") or {}
        spot = args.get("spot")
        if isinstance(spot, dict) and spot.get("spot") and spot["spot"][0] in ("corner", "edge"):
            out.append(str(spot["spot"][1]))
        region = args.get("region")
        if isinstance(region, dict) and isinstance(region.get("region"), dict):
            if region["region"].get("surface_id") is not None:
                out.append(str(region["region"]["surface_id"]))
    return sorted(set(out))


def top_pixels(frame: Any, graph: Any, box: Any) -> np.ndarray:
    """(H, W) bool: depth-map pixels whose 3D point lies on the box's top face (gravity world)."""
    import shapely

    G = np.array((graph.meta.get("gravity") or {}).get("rotation", np.eye(3)), float)
    tol = float((graph.meta.get("thresholds") or {}).get("visibility_tolerance", 0.025))
    cam, depth = frame.camera, np.asarray(frame.depth, float)
    H, W = depth.shape
    corners = np.asarray(box.corners(), float) @ G.T
    z = float(corners[:, 2].max())
    face = shapely.convex_hull(shapely.MultiPoint(corners[:, :2]))
    v, u = np.mgrid[0:H, 0:W]
    pc = cam.backproject((u.ravel() + 0.5), (v.ravel() + 0.5), depth.ravel())
    pose = np.asarray(cam.world_from_cam, float)
    R, o = G @ pose[:3, :3], G @ pose[:3, 3]
    p = pc @ R.T + o
    d = depth.ravel()
    # a depth error e along a ray moves the point e * |o_z - z| / d in height (rays of unit camera depth)
    near = np.abs(p[:, 2] - z) <= tol * abs(o[2] - z) / np.maximum(d, 1e-9)
    keep = (d > 0) & near
    keep[keep] = shapely.contains_xy(face, p[keep, 0], p[keep, 1])
    return keep.reshape(H, W)


def check_surface_seen(qa: Any, frame: Any, graph: Any) -> list[str]:
    """Problems with the surfaces a pair names: a top face too little or too thinly seen, or an object's surface
    whose object is under the floor."""
    sids = named_surfaces(qa)
    if not sids:
        return []
    from refspatial_gen.qa.verify_truth import _below_floor_once

    th = graph.meta.get("thresholds") or {}
    surfaces = {s.id: s for s in frame.surfaces}
    out = []
    for sid in sids:
        s = surfaces.get(sid)
        if s is None:
            continue  # unknown surfaces are reported by the corner/region checks
        if s.object_id is not None and s.object_id in _below_floor_once(frame, graph.meta.get("truth_floor") or {}):
            out.append(f"surface {sid} belongs to object {s.object_id}, below the object floor")
            continue
        if frame.depth is None:
            continue
        cache = frame.__dict__.setdefault("_verify_top_pixels", {})  # one lift of the depth map per surface,
        if sid not in cache:  # not one per pair that names it
            cache[sid] = top_pixels(frame, graph, s.box)
        seen = cache[sid]
        H, W = seen.shape
        need_px = float(th.get("min_surface_px", 0.0)) * W * H / (REF_W * REF_H)
        cols = seen.sum(axis=0)
        rows = float(np.median(cols[cols > 0])) if (cols > 0).any() else 0.0
        need_rows = float(th.get("min_surface_rows", 0.0)) * H / REF_H
        if seen.sum() < need_px * (1 - SLACK):
            out.append(f"surface {sid}: the picture shows {int(seen.sum())} px of its top (< {need_px:.0f})")
        elif rows < need_rows * (1 - SLACK):
            out.append(f"surface {sid}: its seen top is {rows:.1f} px deep (< {need_rows:.1f})")
    return out
