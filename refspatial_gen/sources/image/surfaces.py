"""Support surfaces of a lifted photo: named horizontal planes (a table, the floor) and the ground slab."""

from __future__ import annotations

import numpy as np

from refspatial_gen.core.camera import Camera
from refspatial_gen.core.geometry import Box3D, rot_z
from refspatial_gen.core.model import SupportSurface
from refspatial_gen.sources.image.annotations import GROUND_STUFF_PREFIXES, SUPPORT_STUFF_PREFIXES

# thing categories whose top is a support surface when a horizontal plane lies on them
SUPPORT_CATEGORIES = (
    "dining table",
    "table",
    "desk",
    "bed",
    "counter",
    "bench",
    "night_stand",
    "dresser",
    "coffee_table",
    "sofa",
    "couch",
    "shelf",
    "cabinet",
)


def stuff_kind(name: str) -> str | None:
    n = name.lower()
    if n.startswith(GROUND_STUFF_PREFIXES):
        return "ground"
    if n.startswith(SUPPORT_STUFF_PREFIXES):
        return "support"
    return None


def _surface_box(world_pts: np.ndarray, top_z: float) -> Box3D | None:
    import cv2

    if len(world_pts) < 10:
        return None
    xy = world_pts[:, :2]
    lo, hi = np.percentile(xy, [2, 98], axis=0)
    xy = xy[np.all((xy >= lo) & (xy <= hi), axis=1)]
    if len(xy) < 10:
        return None
    (cx, cy), (w, h), ang = cv2.minAreaRect(xy.astype(np.float32))
    if w <= 0 or h <= 0:
        return None
    return Box3D(np.array([cx, cy, top_z - 0.01]), np.array([w, h, 0.02]), rot_z(np.deg2rad(ang)))


def support_surfaces(
    grav, cam: Camera, depth: np.ndarray, ground: np.ndarray, support_stuff, final, objects, res, est_name: str
) -> list[SupportSurface]:
    """Named horizontal support surfaces only: a plane is named by the object or stuff it lies on (a
    single instance of a support category, or panoptic table/floor stuff) or, when it is the lowest plane
    at least 0.9 m under the camera, 'the floor'. Unnamed planes only serve gravity."""
    out: list[SupportSurface] = []
    H, W = depth.shape
    if est_name == "geometric" or not grav.planes:
        if ground.any() and grav.known and est_name == "geometric":
            ys, xs = np.nonzero(ground & (depth > 0))
            if len(ys) > 50:
                step = max(1, len(ys) // 4000)
                pts = cam.cam_to_world(
                    cam.backproject(xs[::step] + 0.5, ys[::step] + 0.5, depth[ys[::step], xs[::step]])
                )
                b = _surface_box(pts, 0.0)
                if b is not None:
                    out.append(SupportSurface("ground", "floor", b, None, "the ground"))
        return out
    us, vs = grav.detail.get("pixels", (None, None))
    if us is None:
        return out
    cats = [c.category for c in final]
    lowest = min(range(len(grav.planes)), key=lambda i: grav.planes[i].d * -1)
    for i, pl in enumerate(grav.planes):
        pu, pv = us[pl.inliers], vs[pl.inliers]
        top = float(cam.position[2] - pl.d)
        name, kind, oid = None, None, None
        for o, c in zip(objects, final):
            if c.category in SUPPORT_CATEGORIES and cats.count(c.category) == 1:
                m = o.mask.decode()
                if m[pv, pu].mean() > 0.5:
                    name, kind, oid = f"the {c.category.replace('_', ' ')}", "object", o.id
                    break
        if name is None:
            for sname, m in support_stuff:
                if m[pv, pu].mean() > 0.5:
                    name, kind = f"the {sname.split('-')[0]}", "table"
                    break
        if name is None and i == lowest and pl.d >= 0.9:
            name, kind = "the floor", "floor"
        if name is None:
            continue
        zz = depth[pv, pu]
        pts = cam.cam_to_world(cam.backproject(pu + 0.5, pv + 0.5, zz))
        b = _surface_box(pts, top)
        if b is not None:
            out.append(SupportSurface(f"plane{i}", kind, b, oid, name))
    return out
