"""Frames from a settled, rendered scene: object boxes, masks, visible fractions, fronts and supports.

`visible_fraction` = visible mask pixels / area of the object's unclipped silhouette, where the
silhouette is the 2D convex hull of its projected 3D convex hull (exact for convex objects, slightly
large for concave ones such as a mug's handle hole). It therefore counts both occlusion and truncation
at the image border, and costs no extra render.
"""

from __future__ import annotations

import numpy as np

from refspatial_gen.core.camera import Camera
from refspatial_gen.core.geometry import Box3D, rot_z
from refspatial_gen.core.mask import RLE
from refspatial_gen.core.model import Frame, ObjectInstance, SupportSurface
from refspatial_gen.sources.sim.layout import SceneDesc
from refspatial_gen.sources.sim.physics import SimModel, body_pose
from refspatial_gen.sources.sim.render import RenderOut

FRONT_MAX_TILT_Z = 0.7  # a front pointing this much up/down (toppled object) is not a usable front


def world_hull(sim: SimModel, desc: SceneDesc, k: int) -> np.ndarray:
    p, R = body_pose(sim, k)
    return desc.objects[k].geometry.hull_points() @ R.T + p


def gravity_box(points: np.ndarray, R: np.ndarray) -> Box3D:
    """The gravity-aligned (z up) oriented box of world points, yawed with the body's most horizontal axis."""
    axes = [R[:, 0], R[:, 1]]
    a = max(axes, key=lambda v: np.hypot(v[0], v[1]))
    yaw = float(np.arctan2(a[1], a[0])) if a is axes[0] else float(np.arctan2(a[1], a[0]) - np.pi / 2)
    Rz = rot_z(yaw)
    local = points @ Rz
    lo, hi = local.min(axis=0), local.max(axis=0)
    return Box3D(Rz @ ((lo + hi) / 2), hi - lo, Rz)


def silhouette_area(cam: Camera, pts_world: np.ndarray) -> float:
    import cv2

    uv, z = cam.project(pts_world)
    ok = z > 1e-3
    if ok.sum() < 3:
        return 0.0
    hull = cv2.convexHull(uv[ok].astype(np.float32))
    return float(cv2.contourArea(hull))


def scene_boxes(sim: SimModel, desc: SceneDesc) -> list[tuple[Box3D, np.ndarray]]:
    out = []
    for k in range(len(desc.objects)):
        pts = world_hull(sim, desc, k)
        out.append((gravity_box(pts, body_pose(sim, k)[1]), pts))
    return out


def make_frames(
    unit_key: str,
    desc: SceneDesc,
    sim: SimModel,
    cams: list[Camera],
    renders: list[RenderOut],
    boxes: list[tuple[Box3D, np.ndarray]],
    meta: dict,
) -> list[Frame]:
    frames = []
    supports = _object_supports(desc, boxes)
    for v, (cam, r) in enumerate(zip(cams, renders)):
        objects = []
        for k, o in enumerate(desc.objects):
            m = r.instance == k + 1
            n = int(m.sum())
            if n == 0:
                continue
            box, pts = boxes[k]
            cols, rows = np.flatnonzero(m.any(axis=0)), np.flatnonzero(m.any(axis=1))
            sil = silhouette_area(cam, pts)
            vis = float(min(1.0, n / sil)) if sil > 0 else 1.0
            front, phrase = None, None
            if o.category.front is not None:
                fw = body_pose(sim, k)[1] @ np.asarray(o.category.front)
                if abs(fw[2]) < FRONT_MAX_TILT_Z:
                    fb = box.rotation.T @ fw
                    front, phrase = fb / np.linalg.norm(fb), o.category.front_phrase
            objects.append(
                ObjectInstance(
                    id=k + 1,
                    category=o.category.label,
                    box=box,
                    mask=RLE.encode(m),
                    bbox2d=(float(cols[0]), float(rows[0]), float(cols[-1] + 1), float(rows[-1] + 1)),
                    visible_fraction=round(vis, 4),
                    attributes={"color": o.color, "material": o.material},
                    front=front,
                    front_phrase=phrase,
                    provenance={
                        "source": "sim",
                        "asset": o.category.name,
                        "support": supports[k],
                        "pixels": n,
                        **({"finish": dict(o.finish)} if o.finish else {}),
                    },
                )
            )
        visible = {ob.id for ob in objects}
        surfaces = []
        for s in desc.surfaces:
            (x, y), (hx, hy) = (s.face[:2], s.face[2:]) if s.face is not None else (s.center, s.half)
            t = max(s.thickness, 0.01)
            surfaces.append(
                SupportSurface(
                    s.id,
                    s.kind,
                    Box3D(np.array([x, y, s.z - t / 2]), np.array([2 * hx, 2 * hy, t]), np.eye(3)),
                    None,
                    s.name,
                )
            )
        for k in sorted({int(sp[4:]) for sp in supports if sp.startswith("obj:")}):
            if k + 1 in visible:
                surfaces.append(SupportSurface(f"obj:{k + 1}", "object", boxes[k][0], k + 1, None))
        frames.append(
            Frame(
                f"{unit_key}/v{v}",
                r.rgb,
                r.depth,
                cam,
                objects,
                surfaces,
                source="sim",
                scene_id=unit_key,
                meta={**meta, "view": v, "n_views": len(cams)},
            )
        )
    return frames


def _object_supports(desc: SceneDesc, boxes: list[tuple[Box3D, np.ndarray]]) -> list[str]:
    """What each settled object rests on: "obj:<index>", a surface id, or "inside:<index>" for containers."""
    out = []
    for k, (b, _) in enumerate(boxes):
        best = None
        for j, (a, _) in enumerate(boxes):
            if j == k:
                continue
            lo_a, hi_a = a.aabb()
            c = b.center
            if lo_a[0] <= c[0] <= hi_a[0] and lo_a[1] <= c[1] <= hi_a[1]:
                if abs(b.bottom_z - a.top_z) < 0.015:
                    best = f"obj:{j}"
                elif desc.objects[j].geometry.cavity is not None and lo_a[2] - 0.01 <= b.bottom_z < a.top_z - 0.005:
                    best = f"inside:{j}"
        if best is None:
            cands = [
                s
                for s in desc.surfaces
                if abs(b.bottom_z - s.z) < 0.02 and np.all(np.abs(b.center[:2] - s.center) <= s.half + 0.02)
            ]
            best = cands[0].id if cands else "unknown"
        out.append(best)
    return out
