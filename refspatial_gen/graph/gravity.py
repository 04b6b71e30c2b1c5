"""Where "up" is: the frame's gravity when known, else a support plane fitted to the depth map.

Why: world-frame relations (above, tall, on, free space, ...) need a gravity-aligned frame. A source
without gravity must not have it guessed silently: we fit the dominant roughly-horizontal plane with
open3d RANSAC and record that we did, or report that gravity is unknown so that the builder limits the
graph to camera- and image-frame relations.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Any

import numpy as np

from refspatial_gen.core.model import Frame

# A fitted plane is accepted as the support plane only when its normal is within this angle of the
# camera's up (-y) and holds at least this share of the sampled depth points.
MAX_TILT_FROM_CAMERA_UP = np.deg2rad(60.0)
MIN_INLIER_SHARE = 0.10
PLANE_DISTANCE = 0.015  # m, RANSAC inlier distance
MAX_PLANES = 3


@dataclass
class Gravity:
    """`rotation` maps the frame's world coordinates to a gravity-aligned world (z up)."""

    known: bool
    rotation: np.ndarray = field(default_factory=lambda: np.eye(3))
    method: str = "frame"  # "frame" | "fitted_plane" | "unknown"
    detail: dict[str, Any] = field(default_factory=dict)

    def to_json(self) -> dict[str, Any]:
        out = {"known": self.known, "method": self.method, **self.detail}
        if self.method == "fitted_plane":
            out["rotation"] = [[round(float(x), 8) for x in row] for row in self.rotation]
        return out


def _rotation_to_z(up: np.ndarray) -> np.ndarray:
    """Smallest rotation taking unit vector `up` to +z."""
    up = up / np.linalg.norm(up)
    z = np.array([0.0, 0.0, 1.0])
    v = np.cross(up, z)
    s, c = np.linalg.norm(v), float(up @ z)
    if s < 1e-9:
        return np.eye(3) if c > 0 else np.diag([1.0, -1.0, -1.0])
    vx = np.array([[0, -v[2], v[1]], [v[2], 0, -v[0]], [-v[1], v[0], 0]])
    return np.eye(3) + vx + vx @ vx * ((1 - c) / s**2)


def fit_up_from_depth(frame: Frame, seed: int = 0) -> tuple[np.ndarray | None, dict[str, Any]]:
    """Up direction in camera coordinates from the largest roughly-horizontal plane, or None."""
    import open3d as o3d

    cam = frame.camera
    stride = max(1, int(round(np.sqrt(cam.width * cam.height / 40000))))
    vs, us = np.mgrid[0 : cam.height : stride, 0 : cam.width : stride]
    z = frame.depth[::stride, ::stride]
    ok = z > 0
    if ok.sum() < 500:
        return None, {"reason": "too_few_depth_points"}
    pts = cam.backproject(us[ok], vs[ok], z[ok])
    pcd = o3d.geometry.PointCloud(o3d.utility.Vector3dVector(pts))
    o3d.utility.random.seed(seed)
    cam_up = np.array([0.0, -1.0, 0.0])
    best = None
    total = len(pts)
    for _ in range(MAX_PLANES):
        if len(pcd.points) < 200:
            break
        (a, b, c, d), inl = pcd.segment_plane(PLANE_DISTANCE, 3, 200)
        n = np.array([a, b, c])
        n /= np.linalg.norm(n)
        if d < 0:  # orient the normal towards the camera (origin): n.p + d = 0, origin side has sign of d
            n, d = -n, -d
        tilt = float(np.arccos(np.clip(n @ cam_up, -1, 1)))
        share = len(inl) / total
        if tilt <= MAX_TILT_FROM_CAMERA_UP and share >= MIN_INLIER_SHARE and (best is None or share > best[1]):
            best = (n, share, tilt)
        pcd = pcd.select_by_index(inl, invert=True)
    if best is None:
        return None, {"reason": "no_horizontal_plane"}
    return best[0], {
        "inlier_share": round(float(best[1]), 4),
        "tilt_from_camera_up_deg": round(float(np.rad2deg(best[2])), 2),
    }


def resolve_gravity(frame: Frame, fit_plane: bool = True) -> Gravity:
    """The frame's gravity, or a fitted one (recorded), or `known=False`."""
    if frame.camera.gravity_known:
        return Gravity(True, np.eye(3), "frame")
    if not fit_plane:
        return Gravity(False, np.eye(3), "unknown", {"reason": "fitting_disabled"})
    up_cam, info = fit_up_from_depth(frame)
    if up_cam is None:
        return Gravity(False, np.eye(3), "unknown", info)
    up_world = frame.camera.world_from_cam[:3, :3] @ up_cam
    return Gravity(True, _rotation_to_z(up_world), "fitted_plane", info)
