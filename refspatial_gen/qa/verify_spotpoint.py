"""verify's own re-check that a corner / edge free-space answer point lies at its corner / along its edge (the
generator's rule: graph/corner_point.py, audit round 5: "the near-left corner" pointed 46% of the way back).

Why its own code: verify rebuilds the surface's top face from the stored box and gravity, picks the named vertex or
side from the stored camera (qa/verify_corners.py), casts the ray through the answer pixel's centre onto the top
face's plane, and measures the hit's share of the face's extent from the corner along each side, or from the edge
across the face; more than the graph's `corner_point_max_share` (+ `SHARE_TOL` for the float path) is a problem.
"""

from __future__ import annotations

from typing import Any

import numpy as np

SHARE_TOL = 0.01


def _region_point(qa: Any) -> tuple[dict[str, Any], tuple[float, float]] | None:
    s = qa.answer_struct or {}
    reg, pts = s.get("region") or {}, s.get("points") or []
    if s.get("kind") != "region" or reg.get("kind") not in ("corner", "edge") or len(pts) != 1:
        return None
    return reg, (float(pts[0][0]), float(pts[0][1]))


def _hit(view: Any, p: tuple[float, float], z: float) -> np.ndarray | None:
    """Gravity-world xy where the ray through the answer pixel's centre meets the plane at height z."""
    cam = view.cam
    x, y = int(np.floor(p[0] * cam.width)), int(np.floor(p[1] * cam.height))
    d = view.R @ np.array([(x + 0.5 - cam.cx) / cam.fx, (y + 0.5 - cam.cy) / cam.fy, 1.0])
    if abs(d[2]) < 1e-12 or (z - view.o[2]) / d[2] <= 0:
        return None
    return (view.o + (z - view.o[2]) / d[2] * d)[:2]


def spot_share(poly: np.ndarray, kind: str, k: int, xy: np.ndarray) -> float:
    """Share of the face's extent by which xy lies from vertex k (corner: the larger of both sides' shares) or
    from side k -> k+1 (edge: across the face)."""
    if kind == "corner":
        out = 0.0
        for j in ((k + 1) % 4, (k - 1) % 4):
            side = poly[j] - poly[k]
            n = float(np.linalg.norm(side))
            out = max(out, abs(float((xy - poly[k]) @ side)) / max(n * n, 1e-18))
        return out
    e = poly[(k + 1) % 4] - poly[k]
    normal = np.array([-e[1], e[0]]) / max(float(np.linalg.norm(e)), 1e-12)
    across = np.abs((poly - poly[k]) @ normal).max()
    return abs(float((xy - poly[k]) @ normal)) / max(float(across), 1e-9)


def check_spot_point(qa: Any, frame: Any, graph: Any) -> list[str]:
    """Problems with a corner / edge region's answer point (empty for any other pair)."""
    from refspatial_gen.qa.verify_corners import _View, _where

    got = _region_point(qa)
    surfaces = {s.id: s for s in frame.surfaces}
    if got is None or got[0].get("surface_id") not in surfaces:
        return []  # no corner/edge point, or an unknown surface (check_corners says so)
    reg, p = got
    view = _View(frame, graph)
    limit = float(view.th.get("corner_point_max_share", 0.25))
    poly, z = view.top_face(surfaces[reg["surface_id"]].box)
    name = str(reg.get("label", "")).removesuffix(" corner")
    k = _where(view, poly, reg["kind"], name)
    xy = _hit(view, p, z)
    if k is None or xy is None:
        return []  # a name no vertex/side carries is check_corners' problem; an unseen plane check_free_point's
    share = spot_share(poly, reg["kind"], k, xy)
    if share > limit + SHARE_TOL:
        return [f"answer point {p} lies {share:.2f} of {reg['surface_id']}'s extent from its {name} (> {limit})"]
    return []
