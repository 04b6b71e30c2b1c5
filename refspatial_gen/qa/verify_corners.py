"""verify's own re-check that a named corner or edge of a surface is one a person sees (the generator's rule:
graph/surface_seen.py).

Why its own code: the generator withholds a corner or edge name when the surface's plane goes on past the named
side (a bed's mattress beyond its declared surface, audit round 4) or when the picture hardly shows the surface
there (a scan's floor corner with only a sliver of floor in view). verify rebuilds the surface's top face from
the stored box and gravity, names its corners and sides from the stored camera, projects its own sample lattice
(offset from the generator's) with the pinhole model and reads the stored depth map, sharing no code with the
generator. Shares are compared with `SHARE_TOL` of slack for the different lattice.
"""

from __future__ import annotations

from typing import Any

import numpy as np

from refspatial_gen.qa.verify_surface_seen import check_surface_seen

SHARE_TOL = 0.08
N = 10  # lattice cells per side (the generator uses 12)


def _spots(qa: Any) -> list[tuple[str, str, str]]:
    """(kind, surface id, name) of every corner or edge a pair's program relies on ("near-left", "far edge")."""
    out = []
    for st in qa.program or []:
        args = st.get("args") or {}
        spot = (args.get("spot") or {}).get("spot") if isinstance(args.get("spot"), dict) else None
        if spot and spot[0] in ("corner", "edge"):
            out.append((str(spot[0]), str(spot[1]), str(spot[2])))
        region = (args.get("region") or {}).get("region") if isinstance(args.get("region"), dict) else None
        if region and region.get("kind") in ("corner", "edge"):
            name = str(region.get("label", "")).removesuffix(" corner")
            out.append((str(region["kind"]), str(region["surface_id"]), name))
    return out


class _View:
    """The stored frame seen in the gravity world: projection and depth readings."""

    def __init__(self, frame: Any, graph: Any) -> None:
        self.G = np.array((graph.meta.get("gravity") or {}).get("rotation", np.eye(3)), float)
        self.cam, self.depth = frame.camera, np.asarray(frame.depth, float)
        self.th = graph.meta.get("thresholds") or {}
        pose = np.asarray(self.cam.world_from_cam, float)
        self.R, self.o = self.G @ pose[:3, :3], self.G @ pose[:3, 3]  # camera axes / position, gravity world

    def read(self, xy: np.ndarray, z: float) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Plane points -> (their camera depth, the depth map there or 0, seen in the image)."""
        pc = (np.column_stack([xy, np.full(len(xy), z)]) - self.o) @ self.R  # rows: camera-frame points
        zc = pc[:, 2]
        front = zc > 1e-9
        safe = np.where(front, zc, 1.0)
        u = np.floor(self.cam.fx * pc[:, 0] / safe + self.cam.cx)
        v = np.floor(self.cam.fy * pc[:, 1] / safe + self.cam.cy)
        ok = front & (u >= 0) & (u < self.cam.width) & (v >= 0) & (v < self.cam.height)
        d = np.zeros(len(xy))
        d[ok] = self.depth[v[ok].astype(int), u[ok].astype(int)]
        return zc, d, ok

    def top_face(self, box: Any) -> tuple[np.ndarray, float]:
        """The box's top face corners (4, 2) counter-clockwise and its height, in the gravity world."""
        c = np.asarray(box.corners(), float) @ self.G.T
        top = c[np.argsort(-c[:, 2], kind="stable")[:4]]
        m = top[:, :2].mean(axis=0)
        order = np.argsort(np.arctan2(top[:, 1] - m[1], top[:, 0] - m[0]), kind="stable")
        return top[order, :2], float(c[:, 2].max())

    def axes(self) -> tuple[np.ndarray, np.ndarray]:
        r = self.R[:, 0].copy()
        r[2] = 0.0
        r /= np.linalg.norm(r) + 1e-12
        return r[:2], np.array([-r[1], r[0]])  # right, forward (z x right)


def _cells(o: np.ndarray, a: np.ndarray, b: np.ndarray, na: int, nb: int) -> np.ndarray:
    s, t = (np.arange(na) + 0.25) / na, (np.arange(nb) + 0.75) / nb  # offset from the generator's centres
    return np.array([o + x * a + y * b for x in s for y in t])


def _continues(view: _View, p: np.ndarray, q: np.ndarray, z: float) -> float:
    """Share of the depth readings just outside side p->q that show the plane (height and depth agree)."""
    e = q - p
    out = np.array([e[1], -e[0]]) / (np.linalg.norm(e) + 1e-12)
    band = float(view.th.get("extent_band", 0.1))
    zc, d, ok = view.read(_cells(p + 0.2 * band * out, e, 0.8 * band * out, N, 4), z)
    seen = ok & (d > 0)
    if seen.sum() < 6:
        return 0.0
    rise = abs(view.o[2] - z) * np.abs(d - zc) / np.maximum(zc, 1e-9)
    flat = (np.abs(d - zc) <= float(view.th.get("visibility_tolerance", 0.025))) & (
        rise <= float(view.th.get("extent_height_tolerance", 0.012))
    )
    return float((seen & flat).sum() / seen.sum())


def _shown(view: Any, frame: Any, pts: np.ndarray, z: float, side: float) -> float:
    """Share of the samples where the depth map shows the plane, or something in front of it over an object
    standing on the plane whose bounding footprint is at most 2 side x side."""
    import shapely

    tol, gap = float(view.th.get("visibility_tolerance", 0.025)), float(view.th.get("support_gap", 0.05))
    zc, d, ok = view.read(pts, z)
    shown = ok & (d > 0) & (np.abs(d - zc) <= tol)
    feet = []
    for ob in frame.objects:
        c = np.asarray(ob.box.corners(), float) @ view.G.T
        small = np.prod(np.ptp(c[:, :2], axis=0)) <= 2.0 * side * side
        if abs(c[:, 2].min() - z) <= gap and c[:, 2].max() > z and small:
            feet.append(shapely.convex_hull(shapely.MultiPoint(c[:, :2])))
    if feet:
        under = shapely.contains_xy(shapely.union_all(feet), pts[:, 0], pts[:, 1])
        shown |= ok & (d > 0) & (d < zc + tol) & under
    return float(shown.mean()) if len(pts) else 0.0


def _where(view: _View, poly: np.ndarray, kind: str, name: str) -> int | None:
    """The vertex (corner) or the side's first vertex (edge) that the viewer's name picks."""
    right, fwd = view.axes()
    rel = poly - poly.mean(axis=0)
    if kind == "corner":
        names = [("far" if r @ fwd > 0 else "near") + "-" + ("right" if r @ right > 0 else "left") for r in rel]
        return names.index(name) if names.count(name) == 1 else None
    want = {"right edge": right, "far edge": fwd, "left edge": -right, "near edge": -fwd}.get(name)
    if want is None:
        return None
    normals = [np.array([e[1], -e[0]]) / (np.linalg.norm(e) + 1e-12) for e in np.roll(poly, -1, axis=0) - poly]
    return int(np.argmax([n @ want for n in normals]))


def check_corners(qa: Any, frame: Any, graph: Any) -> list[str]:
    """Problems with the corners and edges a pair names (empty when it names none)."""
    from refspatial_gen.qa.verify_spotpoint import check_spot_point

    out = check_surface_seen(qa, frame, graph)  # the named surface's top seen at all (qa/verify_surface_seen.py)
    out += check_spot_point(qa, frame, graph)  # the answer point at its corner / edge (qa/verify_spotpoint.py)
    spots = _spots(qa)
    if not spots or frame.depth is None:
        return out
    view = _View(frame, graph)
    surfaces = {s.id: s for s in frame.surfaces}
    for kind, sid, name in spots:
        if sid not in surfaces:
            out.append(f"{kind} {name!r} of unknown surface {sid!r}")
            continue
        poly, z = view.top_face(surfaces[sid].box)
        k = _where(view, poly, kind, name)
        if k is None:
            out.append(f"{kind} {name!r} of {sid} names no side or corner of its top face from this view")
            continue
        sides = [(k - 1) % 4, k] if kind == "corner" else [k]
        worst = max(_continues(view, poly[j], poly[(j + 1) % 4], z) for j in sides)
        if worst > float(view.th.get("max_extent_continuation", 0.5)) + SHARE_TOL:
            out.append(f"{kind} {name!r} of {sid}: the surface goes on past it ({worst:.2f} of the band)")
        out += _seen(view, frame, poly, z, kind, name, sid, k)
    return out


def _seen(view: _View, frame: Any, poly: np.ndarray, z: float, kind: str, name: str, sid: str, k: int) -> list[str]:
    th = view.th

    def g(key: str, default: float) -> float:
        return float(th.get(key, default))

    side = max(g("corner_size", 0.2), g("corner_reach", 0.15) + g("surface_band_margin", 0.0))
    if kind == "corner":
        e1, e2 = poly[(k + 1) % 4] - poly[k], poly[(k - 1) % 4] - poly[k]
        e1 = e1 / np.linalg.norm(e1) * min(side, np.linalg.norm(e1) / 2)
        e2 = e2 / np.linalg.norm(e2) * min(side, np.linalg.norm(e2) / 2)
        pts, need = _cells(poly[k], e1, e2, N, N), g("min_corner_seen", 0.5)
    else:
        width = max(g("edge_width", 0.1), g("edge_band", 0.08) + g("surface_band_margin", 0.0))
        e = poly[(k + 1) % 4] - poly[k]
        inward = np.array([-e[1], e[0]]) / (np.linalg.norm(e) + 1e-12) * min(width, float(np.linalg.norm(e)) / 2)
        pts, need = _cells(poly[k], e, inward, 3 * N, 4), g("min_edge_seen", 0.5)
    share = _shown(view, frame, pts, z, side)
    if share < need - SHARE_TOL:
        return [f"{kind} {name!r} of {sid}: the picture shows {share:.2f} of it (< {need})"]
    return []
