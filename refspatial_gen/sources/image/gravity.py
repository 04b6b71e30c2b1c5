"""Gravity and the world frame of a single photo.

World frame (same as SUN RGB-D's upright frame): origin on the floor under the camera when the floor
height is known (else at the camera), z up, y = the camera's forward direction made horizontal, x to
the right. Gravity comes from the largest near-horizontal plane (RANSAC on the depth points outside
the objects) or from the recipe's camera prior; when neither applies, `gravity_known=False` and the
frame is built from the camera's own "up" so boxes still exist, but world relations must be skipped.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from refspatial_gen.depth.planes import Plane, horizontal_planes


@dataclass
class GravityEstimate:
    up_cam: np.ndarray  # unit world-up in camera coordinates
    known: bool
    origin: str  # "plane_ransac" | "prior" | "unknown"
    camera_height: float | None  # metres above the lowest horizontal plane found (or the prior)
    planes: list[Plane] = field(default_factory=list)  # camera-frame horizontal planes, largest first
    walls: list[Plane] = field(default_factory=list)  # camera-frame vertical planes (n horizontal)
    detail: dict = field(default_factory=dict)


def world_from_cam(up_cam: np.ndarray, camera_height: float | None) -> np.ndarray:
    """4x4 world-from-camera pose for the upright frame described in the module docstring."""
    z = np.asarray(up_cam, float)
    z = z / np.linalg.norm(z)
    x = np.array([1.0, 0.0, 0.0]) - z[0] * z
    if np.linalg.norm(x) < 1e-6:  # camera x axis vertical (portrait held sideways): use forward instead
        x = np.array([0.0, 0.0, 1.0]) - z[2] * z
        x = np.cross(x / np.linalg.norm(x), z)
    x /= np.linalg.norm(x)
    y = np.cross(z, x)
    R_cw = np.stack([x, y, z], axis=1)  # columns: world axes in camera coordinates
    T = np.eye(4)
    T[:3, :3] = R_cw.T
    T[:3, 3] = [0.0, 0.0, camera_height if camera_height is not None else 0.0]
    return T


def estimate_gravity(points_cam: np.ndarray, rng: np.random.Generator, prior_up: np.ndarray,
                     max_tilt_deg: float = 40.0, min_inlier_fraction: float = 0.08,
                     min_inliers: int = 300) -> GravityEstimate | None:
    """Gravity from the largest near-horizontal plane among `points_cam` (background points, camera frame).

    Returns None when no plane with enough support exists (the caller decides: prior or unknown)."""
    P = np.asarray(points_cam, float)
    if len(P) < min_inliers:
        return None
    zmed = float(np.median(P[:, 2]))
    thresh = max(0.015, 0.01 * zmed)
    need = max(min_inliers, int(min_inlier_fraction * len(P)))
    planes = horizontal_planes(P, rng, prior_up, thresh, need, max_planes=3, max_tilt=np.deg2rad(max_tilt_deg))
    if not planes:
        return None
    # a second "plane" within 10 cm of a bigger one is the same surface's edge or bevel, not a new level
    kept: list[Plane] = []
    for pl in planes:
        if all(abs(pl.d - k.d) >= 0.10 for k in kept):
            kept.append(pl)
    planes = kept
    up = planes[0].n / np.linalg.norm(planes[0].n)
    rest = np.ones(len(P), bool)
    for pl in planes:
        rest[pl.inliers] = False
    walls = find_walls(P[rest], rng, up, thresh, need)
    heights = [pl.d for pl in planes]  # distance of the camera above each plane (n up, camera at origin)
    cam_h = float(max(heights)) if max(heights) > 0 else None
    tilt = float(np.rad2deg(np.arccos(np.clip(up @ prior_up, -1, 1))))
    return GravityEstimate(up, True, "plane_ransac", cam_h, planes, walls,
                           {"walls": len(walls), "plane_inliers": [int(len(p.inliers)) for p in planes],
                            "plane_heights": [round(float(h), 4) for h in heights], "tilt_from_prior_deg": round(tilt, 3),
                            "threshold_m": round(thresh, 4)})


def find_walls(points: np.ndarray, rng: np.random.Generator, up: np.ndarray, thresh: float, min_inliers: int,
               max_walls: int = 2) -> list[Plane]:
    """Up to `max_walls` large vertical planes (normal within 10 degrees of horizontal), largest first.
    Lifting removes their points from box-annotated objects (the wall behind a bed)."""
    from refspatial_gen.depth.planes import ransac_plane

    P = np.asarray(points, float)
    out: list[Plane] = []
    remaining = np.arange(len(P))
    for _ in range(max_walls):
        if len(remaining) < min_inliers:
            break
        best = ransac_plane(P[remaining], rng, thresh, None, vertical_to=up)
        if best is None or len(best.inliers) < min_inliers:
            break
        out.append(Plane(best.n, best.d, remaining[best.inliers]))
        remaining = np.delete(remaining, best.inliers)
    return out
