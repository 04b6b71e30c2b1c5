"""The image mask of a free-space region: every pixel whose point would pass `graph.freespace.check_free_point`.

Why: RefSpatial-Bench scores placement by "the point falls inside the free-space mask", and the region
reward grades a point by its distance to that mask. The mask applies the checker's tests to all pixels
at once (ray meets the surface plane in front of the camera; the hit lies on the support surface, inside
the region polygon, off every obstacle footprint; the depth map sees the surface there), so a pixel is in
the mask exactly when the checker accepts its centre (tests/test_rewards.py compares the two).
"""

from __future__ import annotations

import numpy as np


def region_mask(frame_meta: dict, graph: dict, region: dict, depth: np.ndarray) -> np.ndarray:
    """(H, W) bool mask of the region `{surface_id, kind, anchors, label}` named in a QA's answer_struct."""
    import shapely

    from refspatial_gen.core.geometry import Box3D
    from refspatial_gen.core.model import Frame, SceneGraph
    from refspatial_gen.graph.freespace import gravity_rotation, obstacle_footprints
    from refspatial_gen.graph.scene import points_in_polygons
    from refspatial_gen.graph.support import surface_polygon

    H, W = depth.shape
    frame = Frame.from_meta_json(frame_meta, np.zeros((H, W, 3), np.uint8), depth)
    sg = SceneGraph.from_json(graph)
    reg = _find(sg, region)
    if reg is None:
        raise ValueError(f"free-space region {region} is not in the scene graph of {frame_meta['frame_id']}")
    th = sg.meta.get("thresholds", {})
    tol = float(th.get("visibility_tolerance", 0.025))
    gap = float(th.get("support_gap", 0.05))
    G = gravity_rotation(sg)
    cam = frame.camera
    R = G @ cam.world_from_cam[:3, :3]
    o = G @ cam.world_from_cam[:3, 3]
    # rays through every pixel centre, kept only where they meet the plane inside the region's bounding box
    u = (np.arange(W, dtype=np.float64) + 0.5 - cam.cx) / cam.fx
    v = (np.arange(H, dtype=np.float64) + 0.5 - cam.cy) / cam.fy
    dz = R[2, 0] * u[None, :] + R[2, 1] * v[:, None] + R[2, 2]
    with np.errstate(divide="ignore", invalid="ignore"):
        t = (reg.z - o[2]) / dz
    t = np.where((np.abs(dz) >= 1e-12) & np.isfinite(t) & (t > 0), t, np.nan)
    hx = o[0] + t * (R[0, 0] * u[None, :] + R[0, 1] * v[:, None] + R[0, 2])
    hy = o[1] + t * (R[1, 0] * u[None, :] + R[1, 1] * v[:, None] + R[1, 2])
    poly = np.asarray(reg.polygon_xy, float)
    (x0, y0), (x1, y1) = poly.min(axis=0), poly.max(axis=0)
    with np.errstate(invalid="ignore"):
        idx = np.flatnonzero(((hx >= x0) & (hx <= x1) & (hy >= y0) & (hy <= y1)).ravel())
    xy = np.column_stack([hx.ravel()[idx], hy.ravel()[idx]])
    surf = {s.id: s for s in frame.surfaces}.get(reg.surface_id)
    if surf is None:
        return np.zeros((H, W), bool)
    outline = surface_polygon(Box3D(G @ surf.box.center, surf.box.size, G @ surf.box.rotation))
    keep = points_in_polygons(xy, outline[None])[0]
    keep &= shapely.contains_xy(shapely.polygons(poly), xy[:, 0], xy[:, 1])
    fps = obstacle_footprints(frame, G, reg.z, gap)
    if len(fps):
        keep &= ~points_in_polygons(xy, np.asarray(fps, float)).any(axis=0)
    idx = idx[keep]
    pts = np.column_stack([hx.ravel()[idx], hy.ravel()[idx], np.full(len(idx), reg.z)])
    z_cam = cam.world_to_cam(pts @ G)[:, 2]  # G.T @ hit for each row = hit @ G
    dep = depth.reshape(-1)[idx]
    idx = idx[(dep > 0) & (np.abs(dep - z_cam) <= tol)]
    out = np.zeros(H * W, bool)
    out[idx] = True
    return out.reshape(H, W)


def _find(graph, r: dict):
    """The region an answer_struct names (the rule of qa.verify's lookup: surface, kind, anchors, label)."""
    for reg in graph.free_space:
        if (
            reg.surface_id == r.get("surface_id")
            and reg.kind == r.get("kind")
            and list(reg.anchors) == list(r.get("anchors") or [])
            and reg.label == r.get("label", reg.label)
        ):
            return reg
    return None
