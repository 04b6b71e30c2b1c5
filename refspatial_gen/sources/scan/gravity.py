"""Making a world frame z-up when the scan does not say where gravity points: fit the floor plane.

Readers with a known gravity (SUN RGB-D's Rtilt, ScanNet's z-up scan frame, a given up vector) never
call this. Otherwise the floor is the lowest large plane whose normal is within `max_tilt` of a hint
(the cameras' mean "image up" direction); when none is found the frame keeps gravity_known=False.
"""

from __future__ import annotations

import numpy as np


def rotation_between(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """The smallest rotation taking unit vector a onto unit vector b."""
    a = np.asarray(a, float) / np.linalg.norm(a)
    b = np.asarray(b, float) / np.linalg.norm(b)
    v = np.cross(a, b)
    c = float(a @ b)
    if np.linalg.norm(v) < 1e-12:
        if c > 0:
            return np.eye(3)
        axis = np.cross(a, [1.0, 0, 0]) if abs(a[0]) < 0.9 else np.cross(a, [0, 1.0, 0])
        axis /= np.linalg.norm(axis)
        return 2 * np.outer(axis, axis) - np.eye(3)
    vx = np.array([[0, -v[2], v[1]], [v[2], 0, -v[0]], [-v[1], v[0], 0]])
    return np.eye(3) + vx + vx @ vx * (1 / (1 + c))


def up_aligning_transform(up: np.ndarray, floor_point: np.ndarray | None = None) -> np.ndarray:
    """4x4 rigid transform that maps world `up` to +z (and `floor_point` to z = 0 when given)."""
    T = np.eye(4)
    T[:3, :3] = rotation_between(up, np.array([0.0, 0.0, 1.0]))
    if floor_point is not None:
        T[2, 3] = -float((T[:3, :3] @ np.asarray(floor_point, float))[2])
    return T


def fit_floor(
    points: np.ndarray,
    up_hint: np.ndarray,
    rng: np.random.Generator,
    max_tilt_deg: float = 30.0,
    inlier_dist: float = 0.02,
    iterations: int = 300,
    min_fraction: float = 0.05,
    max_planes: int = 3,
) -> tuple[np.ndarray, np.ndarray, float] | None:
    """Lowest large near-horizontal plane -> (unit normal pointing up, a point on it, inlier fraction), or None."""
    pts = np.asarray(points, float)
    up_hint = np.asarray(up_hint, float) / np.linalg.norm(up_hint)
    n_total = len(pts)
    if n_total < 50:
        return None
    cos_tilt = np.cos(np.deg2rad(max_tilt_deg))
    planes = []
    remaining = pts
    for _ in range(max_planes):
        if len(remaining) < 50:
            break
        best = None
        for _ in range(iterations):
            tri = remaining[rng.choice(len(remaining), 3, replace=False)]
            n = np.cross(tri[1] - tri[0], tri[2] - tri[0])
            nn = np.linalg.norm(n)
            if nn < 1e-9:
                continue
            n /= nn
            if n @ up_hint < 0:
                n = -n
            if n @ up_hint < cos_tilt:
                continue
            d = (remaining - tri[0]) @ n
            inl = np.abs(d) < inlier_dist
            cnt = int(inl.sum())
            if best is None or cnt > best[0]:
                best = (cnt, n, tri[0], inl)
        if best is None or best[0] < min_fraction * n_total:
            break
        cnt, n, p0, inl = best
        # refine with a least-squares fit on the inliers
        q = remaining[inl]
        c = q.mean(axis=0)
        _, _, vt = np.linalg.svd(q - c, full_matrices=False)
        n2 = vt[2] if vt[2] @ up_hint > 0 else -vt[2]
        planes.append((n2, c, cnt / n_total))
        remaining = remaining[~inl]
    if not planes:
        return None
    # the floor is the lowest of the large horizontal planes (tables and beds are above it)
    return min(planes, key=lambda p: float(p[1] @ up_hint))
