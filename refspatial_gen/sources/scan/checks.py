"""Whole-view checks of a scan frame (pose, depth, blur): each problem is a DropUnit with its own reason code,
so a broken view is dropped and counted, never a traceback."""

from __future__ import annotations

import numpy as np

from refspatial_gen.core.camera import Camera
from refspatial_gen.core.errors import DropUnit


def blur_score(rgb: np.ndarray) -> float:
    """Variance of the Laplacian of the grey image: low means blurred (motion blur, defocus)."""
    import cv2

    grey = cv2.cvtColor(rgb, cv2.COLOR_RGB2GRAY)
    return float(cv2.Laplacian(grey, cv2.CV_64F).var())


def check_pose(cam: Camera) -> None:
    T = cam.world_from_cam
    if not np.all(np.isfinite(T)):
        raise DropUnit("pose_invalid", "camera pose has NaN or infinite entries")
    R = T[:3, :3]
    if (
        abs(np.linalg.det(R) - 1) > 1e-3
        or not np.allclose(R.T @ R, np.eye(3), atol=1e-3)
        or not np.allclose(T[3], [0, 0, 0, 1])
    ):
        raise DropUnit("pose_invalid", "camera pose is not a rigid transform")
    for name in ("fx", "fy", "cx", "cy"):
        if not np.isfinite(getattr(cam, name)) or (name in ("fx", "fy") and getattr(cam, name) <= 0):
            raise DropUnit("intrinsics_invalid", f"{name}={getattr(cam, name)}")


def check_depth(depth: np.ndarray, shape: tuple[int, int]) -> None:
    if depth.shape != shape:
        raise DropUnit("depth_size_mismatch", f"depth {depth.shape} vs image {shape}")
    if not np.all(np.isfinite(depth)):
        raise DropUnit("depth_nan", f"{int((~np.isfinite(depth)).sum())} NaN/inf depth pixels")
    if np.any(depth < 0):
        raise DropUnit("depth_negative", f"{int((depth < 0).sum())} negative depth pixels")
    if not np.any(depth > 0):
        raise DropUnit("depth_empty", "depth map has no valid pixel")
