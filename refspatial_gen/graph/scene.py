"""Per-frame geometry every relation reads, computed once and vectorised over objects.

Why: relations are many small comparisons over the same quantities (centres, extents, nearest-face
depths, surface-to-surface distances). Computing them here once, as arrays indexed by object position,
keeps graph building in milliseconds and guarantees every relation sees the same numbers.

World quantities are in the gravity-aligned world (the frame's world rotated by `Gravity.rotation`);
camera quantities use the frame's own camera.
"""

from __future__ import annotations

from functools import cached_property
from typing import Any

import numpy as np

from refspatial_gen.core.geometry import Box3D, box_distance
from refspatial_gen.core.mask import answer_pixel, denormalise_point, normalise_point
from refspatial_gen.core.model import Frame, SupportSurface
from refspatial_gen.graph.colour import colour_lab, colour_word, image_white, mask_pixels
from refspatial_gen.graph.constants import Thresholds
from refspatial_gen.graph.gravity import Gravity

UPRIGHT_COS = np.cos(np.deg2rad(2.0))  # a box axis this close to vertical makes the box a vertical prism


_NEXT: dict[int, np.ndarray] = {}


def roll_next(a: np.ndarray, axis: int = 0) -> np.ndarray:
    """`np.roll(a, -1, axis)` (each vertex's successor), without np.roll's overhead on tiny arrays."""
    k = a.shape[axis]
    idx = _NEXT.get(k)
    if idx is None:
        idx = _NEXT[k] = (np.arange(k) + 1) % max(k, 1)
    return np.take(a, idx, axis=axis)


def ccw(poly: np.ndarray) -> np.ndarray:
    """The polygon's vertices in counter-clockwise order."""
    x, y = poly[:, 0], poly[:, 1]
    area2 = float(np.sum(x * roll_next(y) - roll_next(x) * y))
    return poly if area2 >= 0 else poly[::-1].copy()


def box_footprint(box: Box3D) -> tuple[np.ndarray, bool]:
    """(4x2 CCW footprint rectangle in xy, upright?). Upright boxes give their exact prism base; tilted
    ones the minimum-area rectangle around their corners' xy."""
    k = int(np.argmax(np.abs(box.rotation[2, :])))
    upright = abs(box.rotation[2, k]) >= UPRIGHT_COS
    if upright:
        a1, a2 = [i for i in range(3) if i != k]
        e1 = box.rotation[:2, a1] * box.size[a1] / 2
        e2 = box.rotation[:2, a2] * box.size[a2] / 2
        c = box.center[:2]
        poly = np.array([c - e1 - e2, c + e1 - e2, c + e1 + e2, c - e1 + e2])
        return ccw(poly), True
    import cv2

    rect = cv2.minAreaRect(box.corners()[:, :2].astype(np.float32))
    return ccw(cv2.boxPoints(rect).astype(np.float64)), False


def points_in_polygons(points: np.ndarray, polys: np.ndarray, pad: float = 0.0) -> np.ndarray:
    """(P, 2) points in each of (M, K, 2) convex CCW polygons -> bool (M, P). `pad` grows the polygons."""
    a = polys
    b = roll_next(polys, axis=1)
    e = b - a  # (M,K,2)
    ln = np.linalg.norm(e, axis=2) + 1e-12
    rel = points[None, None, :, :] - a[:, :, None, :]  # (M,K,P,2)
    cross = (e[:, :, None, 0] * rel[..., 1] - e[:, :, None, 1] * rel[..., 0]) / ln[:, :, None]
    return np.all(cross >= -pad, axis=1)


def polygon_distances(polys: np.ndarray) -> np.ndarray:
    """Pairwise minimum distances between convex CCW polygons (M, K, 2); 0 where they overlap."""
    a = polys[None, :, None, :, :]
    e = (roll_next(polys, axis=1) - polys)[None, :, None, :, :]
    p = polys[:, None, :, None, :]
    ee = np.sum(e * e, axis=-1)
    t = np.clip(np.sum((p - a) * e, axis=-1) / np.maximum(ee, 1e-18), 0.0, 1.0)
    d = np.linalg.norm(p - (a + t[..., None] * e), axis=-1).min(axis=(2, 3))  # vertices of i to edges of j
    d = np.minimum(d, d.T)
    # separating-axis test: overlap when no edge normal of either polygon separates them
    edges = roll_next(polys, axis=1) - polys
    normals = np.stack([-edges[..., 1], edges[..., 0]], axis=-1)  # (M,K,2)
    proj = np.einsum("mkd,npd->mnkp", normals, polys)  # normals of m, vertices of n
    mn, mx = proj.min(axis=3), proj.max(axis=3)  # (M,N,K)
    own_min = np.einsum("mkd,mpd->mkp", normals, polys).min(axis=2)  # (M,K)
    own_max = np.einsum("mkd,mpd->mkp", normals, polys).max(axis=2)
    sep_m = np.any((mx < own_min[:, None, :] - 1e-12) | (mn > own_max[:, None, :] + 1e-12), axis=2)  # (M,N)
    separated = sep_m | sep_m.T
    d[~separated] = 0.0
    return d


class SceneGeom:
    """Arrays over `frame.objects` (position i) plus decoded masks, for one frame."""

    def __init__(self, frame: Frame, th: Thresholds, gravity: Gravity) -> None:
        self.frame = frame
        self.th = th
        self.gravity = gravity
        self.world_ok = gravity.known
        self.cache: dict[str, Any] = {}  # per-frame results of relation groups (matrices), filled lazily
        cam = frame.camera
        self.W, self.H = cam.width, cam.height
        objs = frame.objects
        self.n = n = len(objs)
        self.ids = np.array([o.id for o in objs], dtype=np.int64)
        self.index = {int(o.id): i for i, o in enumerate(objs)}
        self.categories = [o.category for o in objs]
        G = gravity.rotation
        self.boxes = [Box3D(G @ o.box.center, o.box.size, G @ o.box.rotation) for o in objs]
        self.centers = np.array([b.center for b in self.boxes]).reshape(n, 3)
        self.corners = np.array([b.corners() for b in self.boxes]).reshape(n, 8, 3)
        self.lo = self.corners.min(axis=1) if n else np.zeros((0, 3))
        self.hi = self.corners.max(axis=1) if n else np.zeros((0, 3))
        self.height = self.hi[:, 2] - self.lo[:, 2]
        self.volume = np.array([b.volume for b in self.boxes])
        fps = [box_footprint(b) for b in self.boxes]
        self.footprints = np.array([f for f, _ in fps]).reshape(n, 4, 2)
        self.upright = np.array([u for _, u in fps], dtype=bool)
        sides = np.linalg.norm(roll_next(self.footprints, axis=1) - self.footprints, axis=2)  # (n,4)
        self.width = sides.max(axis=1) if n else np.zeros(0)  # larger horizontal extent
        self.footprint_area = sides[:, 0] * sides[:, 1] if n else np.zeros(0)
        # camera frame (the frame's own camera and world)
        self.cam_centers = cam.world_to_cam(np.array([o.box.center for o in objs]).reshape(n, 3))
        cc = cam.world_to_cam(np.array([o.box.corners() for o in objs]).reshape(-1, 3)).reshape(n, 8, 3)
        self.near_depth = cc[:, :, 2].min(axis=1) if n else np.zeros(0)
        self.cam_lo = cc.min(axis=1) if n else np.zeros((0, 3))  # box extents along the camera axes
        self.cam_hi = cc.max(axis=1) if n else np.zeros((0, 3))
        self.center_depth = self.cam_centers[:, 2]
        # camera pose in the gravity world
        self.cam_rot_g = G @ cam.world_from_cam[:3, :3]
        self.cam_pos_g = G @ cam.world_from_cam[:3, 3]
        self._masks()
        # truth floors (graph/visibility.apply_floor fills them when a graph is built)
        self.in_view = np.ones(n)
        self.floor_why: list[str | None] = [None] * n
        self.metric_why: list[str | None] = [None] * n
        self.cut_why: list[str | None] = [None] * n  # cut by the image border: no size question
        self.front_why: list[str | None] = [None] * n  # why its front was taken away (orientation)
        self.fronts = np.full((n, 3), np.nan)
        for i, o in enumerate(objs):
            if o.front is not None:
                self.fronts[i] = G @ o.front_world
        self.has_front = np.all(np.isfinite(self.fronts), axis=1)

    # ---------------------------------------------------------------- masks, points, colours
    def _masks(self) -> None:
        n, W, H = self.n, self.W, self.H
        rgb = self.frame.rgb
        self.mask_area = np.zeros(n, dtype=np.int64)
        self.img_centroid = np.full((n, 2), np.nan)  # normalised
        self.img_rows = np.full((n, 2), np.nan)  # normalised top and bottom rows of the visible mask
        self.img_cols = np.full((n, 2), np.nan)  # normalised left and right columns of the visible mask
        self.points: list[tuple[float, float] | None] = [None] * n
        self.colours: list[str | None] = [None] * n
        self.colour_how: list[str] = ["no_mask"] * n
        self.colour_lab: list[tuple[float, float, float] | None] = [None] * n  # graph/phrases.py: colour words
        self.mask_depth = np.full(n, np.nan)
        self.mask_depth_spread = np.full(n, np.nan)
        depth = self.frame.depth
        white = image_white(rgb) if self.frame.objects else 1.0
        for i, o in enumerate(self.frame.objects):
            if o.mask is None or o.mask.area == 0:
                continue
            full = o.mask.decode()
            rows, cols = np.flatnonzero(full.any(axis=1)), np.flatnonzero(full.any(axis=0))
            y0, y1, x0, x1 = rows[0], rows[-1] + 1, cols[0], cols[-1] + 1
            m = full[y0:y1, x0:x1]
            ys, xs = np.nonzero(m)
            self.mask_area[i] = len(xs)
            self.img_centroid[i] = ((xs.mean() + x0 + 0.5) / W, (ys.mean() + y0 + 0.5) / H)
            self.img_rows[i] = (y0 / H, y1 / H)
            self.img_cols[i] = (x0 / W, x1 / W)
            if o.provenance.get("answer_point") is None:  # a scan source may withhold it (sources/scan/surface.py)
                self.points[i] = valid_point(m, x0, y0, W, H)
            px = mask_pixels(rgb[y0:y1, x0:x1], m)
            self.colour_lab[i] = colour_lab(px, white)
            self.colours[i], self.colour_how[i] = colour_word(
                px,
                o.attributes.get("color"),
                o.category,
                self.th.colour_min_share,
                self.th.colour_margin,
                white,
            )
            ys, xs = ys + y0, xs + x0
            d = depth[ys, xs]
            d = d[d > 0]
            if len(d) >= 5:
                p10, p50, p90 = np.percentile(d, [10, 50, 90])
                self.mask_depth[i] = p50
                self.mask_depth_spread[i] = p90 - p10
        # objects without a visible mask: use the projected box centre for image-plane comparisons
        missing = ~np.isfinite(self.img_centroid[:, 0])
        if missing.any():
            uv, z = self.frame.camera.project_cam(self.cam_centers[missing])
            self.img_centroid[missing] = np.stack([(uv[:, 0] + 0.5) / W, (uv[:, 1] + 0.5) / H], axis=1)

    # ---------------------------------------------------------------- pairwise quantities
    @cached_property
    def surface_distance(self) -> np.ndarray:
        """(n, n) minimum surface-to-surface distance (exact for vertical prisms, sampled otherwise)."""
        n = self.n
        dxy = polygon_distances(self.footprints) if n else np.zeros((0, 0))
        gz = np.maximum(
            0.0, np.maximum(self.lo[None, :, 2] - self.hi[:, None, 2], self.lo[:, None, 2] - self.hi[None, :, 2])
        )
        d = np.sqrt(dxy**2 + gz**2)
        for i in np.flatnonzero(~self.upright):
            for j in range(n):
                if j != i:
                    d[i, j] = d[j, i] = box_distance(self.boxes[i], self.boxes[j])
        np.fill_diagonal(d, 0.0)
        return d

    @cached_property
    def center_distance(self) -> np.ndarray:
        return np.linalg.norm(self.centers[:, None, :] - self.centers[None, :, :], axis=2)

    @cached_property
    def footprint_overlap(self) -> np.ndarray:
        """(n, n): share of i's footprint lying over j's footprint (6x6 sample grid)."""
        n = self.n
        t = (np.arange(6) + 0.5) / 6
        u, v = np.meshgrid(t, t, indexing="ij")
        u, v = u.ravel(), v.ravel()  # type: ignore[assignment]
        f = self.footprints
        pts = (
            f[:, None, 0]
            + u[None, :, None] * (f[:, None, 1] - f[:, None, 0])
            + v[None, :, None] * (f[:, None, 3] - f[:, None, 0])
        )
        inside = points_in_polygons(pts.reshape(-1, 2), f).reshape(n, n, len(u))  # (polygon j, object i, sample)
        out = inside.mean(axis=2).T.copy()
        np.fill_diagonal(out, 0.0)
        return out

    # ---------------------------------------------------------------- surfaces
    @cached_property
    def surfaces(self) -> list[SupportSurface]:
        G = self.gravity.rotation
        return [
            SupportSurface(s.id, s.kind, Box3D(G @ s.box.center, s.box.size, G @ s.box.rotation), s.object_id, s.name)
            for s in sorted(self.frame.surfaces, key=lambda s: s.id)
        ]

    def camera_axes_horizontal(self) -> tuple[np.ndarray, np.ndarray] | None:
        """(right, forward) unit vectors of the camera projected on the ground plane, or None when the
        camera looks straight down (no horizontal forward)."""
        r = self.cam_rot_g[:, 0].copy()
        r[2] = 0.0
        if np.linalg.norm(r) < 1e-6:
            return None
        r /= np.linalg.norm(r)
        f = np.cross(np.array([0.0, 0.0, 1.0]), r)
        return r, f

    def project_world(self, points_g: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Gravity-world points -> (pixel uv, camera depth)."""
        if "_cam_from_g" not in self.cache:
            T = self.frame.camera.cam_from_world
            self.cache["_cam_from_g"] = (T[:3, :3] @ self.gravity.rotation.T, T[:3, 3])
        R, t = self.cache["_cam_from_g"]
        return self.frame.camera.project_cam(np.asarray(points_g, float).reshape(-1, 3) @ R.T + t)


def valid_point(
    mask: np.ndarray, x0: int = 0, y0: int = 0, width: int | None = None, height: int | None = None
) -> tuple[float, float] | None:
    """The object's normalised answer point (core.mask.answer_pixel), guaranteed to fall back inside the
    mask after denormalising. `mask` may be a crop whose top-left pixel is (x0, y0) of a W x H image."""
    H, W = (height or mask.shape[0]), (width or mask.shape[1])
    px = answer_pixel(mask)
    if px is None:
        return None

    def ok(p: tuple[float, float]) -> bool:
        x, y = denormalise_point(p[0], p[1], W, H)
        x, y = x - x0, y - y0
        return 0 <= y < mask.shape[0] and 0 <= x < mask.shape[1] and bool(mask[y, x])

    p = normalise_point(px[0] + x0, px[1] + y0, W, H)
    if ok(p):
        return p
    ys, xs = np.nonzero(mask)
    order = np.argsort((xs - px[0]) ** 2 + (ys - px[1]) ** 2, kind="stable")
    for k in order[:200]:
        p = normalise_point(float(xs[k] + x0), float(ys[k] + y0), W, H)
        if ok(p):
            return p
    return None
