"""Pinhole camera with pose and gravity. Camera frame is OpenCV (x right, y down, z forward)."""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Any

import numpy as np


@dataclass(eq=False)
class Camera:
    """Intrinsics, world-from-camera pose (4x4) and whether the world frame is gravity-aligned (z up).

    `gravity_known=False` means the world frame is arbitrary (e.g. an image with no estimated plane):
    world-frame relations must not be evaluated on such a frame.
    """

    width: int
    height: int
    fx: float
    fy: float
    cx: float
    cy: float
    world_from_cam: np.ndarray = field(default_factory=lambda: np.eye(4))
    gravity_known: bool = True

    def __post_init__(self) -> None:
        self.world_from_cam = np.asarray(self.world_from_cam, dtype=np.float64).reshape(4, 4)

    @property
    def K(self) -> np.ndarray:
        return np.array([[self.fx, 0, self.cx], [0, self.fy, self.cy], [0, 0, 1.0]])

    @property
    def cam_from_world(self) -> np.ndarray:
        return np.linalg.inv(self.world_from_cam)

    @property
    def position(self) -> np.ndarray:
        return self.world_from_cam[:3, 3].copy()

    @property
    def gravity_cam(self) -> np.ndarray:
        """Unit gravity direction (pointing down) expressed in camera coordinates."""
        return self.world_from_cam[:3, :3].T @ np.array([0.0, 0.0, -1.0])

    def world_to_cam(self, points: np.ndarray) -> np.ndarray:
        p = np.asarray(points, float).reshape(-1, 3)
        T = self.cam_from_world
        return p @ T[:3, :3].T + T[:3, 3]

    def cam_to_world(self, points: np.ndarray) -> np.ndarray:
        p = np.asarray(points, float).reshape(-1, 3)
        T = self.world_from_cam
        return p @ T[:3, :3].T + T[:3, 3]

    def project_cam(self, pc: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Camera-frame points -> (pixel uv (N,2), depth z (N,)). Points behind the camera get NaN uv."""
        pc = np.asarray(pc, float).reshape(-1, 3)
        z = pc[:, 2]
        with np.errstate(divide="ignore", invalid="ignore"):
            u = np.where(z > 1e-9, self.fx * pc[:, 0] / z + self.cx, np.nan)
            v = np.where(z > 1e-9, self.fy * pc[:, 1] / z + self.cy, np.nan)
        return np.stack([u, v], axis=1), z

    def project(self, points_world: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """World points -> (pixel uv (N,2), depth z (N,))."""
        return self.project_cam(self.world_to_cam(points_world))

    def backproject(self, u: np.ndarray, v: np.ndarray, z: np.ndarray) -> np.ndarray:
        """Pixels with metric depth -> camera-frame points (N,3). Pixel (u, v) spans [u, u+1): its centre is u + 0.5."""
        u, v, z = (np.asarray(a, float).ravel() for a in (u, v, z))
        return np.stack([(u - self.cx) * z / self.fx, (v - self.cy) * z / self.fy, z], axis=1)

    def depth_to_points(self, depth: np.ndarray, stride: int = 1) -> np.ndarray:
        """Depth map (metres, 0 = unknown) -> world points of the valid pixels (rays through pixel centres)."""
        vs, us = np.mgrid[0 : self.height : stride, 0 : self.width : stride]
        z = depth[::stride, ::stride]
        ok = z > 0
        return self.cam_to_world(self.backproject(us[ok] + 0.5, vs[ok] + 0.5, z[ok]))

    def to_json(self) -> dict[str, Any]:
        return {
            "width": int(self.width),
            "height": int(self.height),
            "fx": float(self.fx),
            "fy": float(self.fy),
            "cx": float(self.cx),
            "cy": float(self.cy),
            "world_from_cam": [[round(float(x), 8) for x in row] for row in self.world_from_cam],
            "gravity_known": bool(self.gravity_known),
        }

    @classmethod
    def from_json(cls, d: dict[str, Any]) -> Camera:
        return cls(
            d["width"],
            d["height"],
            d["fx"],
            d["fy"],
            d["cx"],
            d["cy"],
            np.array(d["world_from_cam"]),
            d.get("gravity_known", True),
        )


def look_at(eye: np.ndarray, target: np.ndarray, up: np.ndarray | None = None) -> np.ndarray:
    """World-from-camera pose (OpenCV axes) for a camera at `eye` looking at `target` (default up: +z)."""
    up = np.array([0.0, 0.0, 1.0]) if up is None else up
    eye, target = np.asarray(eye, float), np.asarray(target, float)
    z = target - eye
    z /= np.linalg.norm(z)
    x = np.cross(z, up)
    if np.linalg.norm(x) < 1e-9:
        x = np.cross(z, np.array([0.0, 1.0, 0.0]))
    x /= np.linalg.norm(x)
    y = np.cross(z, x)
    T = np.eye(4)
    T[:3, 0], T[:3, 1], T[:3, 2], T[:3, 3] = x, y, z, eye
    return T
