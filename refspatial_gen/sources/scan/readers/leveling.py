"""Re-level a view's world frame so z is up: from a given up vector, else from a fitted floor plane."""

from __future__ import annotations

from collections.abc import Callable

import numpy as np

from refspatial_gen.core.camera import Camera
from refspatial_gen.sources.scan.gravity import fit_floor, up_aligning_transform
from refspatial_gen.sources.scan.view import ScanView, boxes_to_world


def apply_world_transform(view: ScanView, T: np.ndarray, gravity_source: str, known: bool) -> ScanView:
    c = view.camera
    view.camera = Camera(c.width, c.height, c.fx, c.fy, c.cx, c.cy, T @ c.world_from_cam, known)
    view.boxes = boxes_to_world(view.boxes, T)
    if view.points is not None:
        view.points = view.points @ T[:3, :3].T + T[:3, 3]
    view.gravity_source = gravity_source
    view.meta["world_leveling"] = [[round(float(x), 8) for x in row] for row in T]
    return view


def level_views(
    view: ScanView, up: np.ndarray | None, scene_points: Callable[[], tuple[np.ndarray, np.ndarray]]
) -> ScanView:
    """`up` given -> rotate it onto +z ("given"). Otherwise fit the floor over the scene's points
    ("floor_plane", floor at z = 0); no floor -> gravity unknown, world left as it is."""
    if up is not None:
        return apply_world_transform(view, up_aligning_transform(up), "given", True)
    pts, up_hint = scene_points()
    fit = fit_floor(pts, up_hint, np.random.default_rng(0)) if len(pts) else None
    if fit is None:
        view.camera.gravity_known = False
        view.gravity_source = "unknown"
        return view
    normal, point, frac = fit
    view.meta["floor_inlier_fraction"] = round(float(frac), 4)
    return apply_world_transform(view, up_aligning_transform(normal, point), "floor_plane", True)
