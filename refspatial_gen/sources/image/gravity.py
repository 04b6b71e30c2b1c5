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

from refspatial_gen.depth.planes import Plane, horizontal_planes, point_normals


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


def estimate_gravity(
    points_cam: np.ndarray,
    rng: np.random.Generator,
    prior_up: np.ndarray,
    max_tilt_deg: float = 40.0,
    min_inlier_fraction: float = 0.08,
    min_inliers: int = 300,
) -> GravityEstimate | None:
    """Gravity from the largest near-horizontal plane among `points_cam` (background points, camera frame).

    Returns None when no plane with enough support exists (the caller decides: prior or unknown)."""
    P = np.asarray(points_cam, float)
    if len(P) < min_inliers:
        return None
    zmed = float(np.median(P[:, 2]))
    thresh = max(0.015, 0.01 * zmed)
    need = max(min_inliers, int(min_inlier_fraction * len(P)))
    # one-point hypotheses (a point and its normal): the floor is found on every seed, not 5 in 6
    normals = point_normals(P, np.sort(rng.choice(len(P), min(len(P), 2000), replace=False)))
    planes = horizontal_planes(
        P, rng, prior_up, thresh, need, max_planes=3, max_tilt=np.deg2rad(max_tilt_deg), normals=normals
    )
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
    walls = find_walls(P[rest], rng, up, thresh, need, normals=normals[rest])
    up = refine_up(up, planes, walls)
    # every level re-expressed with the refined normal (the camera is at the origin, n.p + d = 0)
    planes = [Plane(up, float(np.median(-P[pl.inliers] @ up)), pl.inliers) for pl in planes]
    floor = floor_below(P, up, planes, thresh, max(min_inliers // 2, int(0.02 * len(P))), normals)
    if floor is not None:  # the floor is the truest level: refine once more with it
        pts_floor = P[floor.inliers]
        c0 = pts_floor.mean(axis=0)
        n = np.linalg.svd(pts_floor - c0, full_matrices=False)[2][2]
        planes.append(Plane(n if n @ up > 0 else -n, 0.0, floor.inliers))
        up = refine_up(up, planes, walls)
        planes = [Plane(up, float(np.median(-P[pl.inliers] @ up)), pl.inliers) for pl in planes]
    heights = [pl.d for pl in planes]  # distance of the camera above each plane (n up, camera at origin)
    cam_h = float(max(heights)) if max(heights) > 0 else None
    tilt = float(np.rad2deg(np.arccos(np.clip(up @ prior_up, -1, 1))))
    return GravityEstimate(
        up,
        True,
        "plane_ransac",
        cam_h,
        planes,
        walls,
        {
            "walls": len(walls),
            "plane_inliers": [int(len(p.inliers)) for p in planes],
            "plane_heights": [round(float(h), 4) for h in heights],
            "tilt_from_prior_deg": round(tilt, 3),
            "threshold_m": round(thresh, 4),
        },
    )


def floor_below(
    P: np.ndarray,
    up: np.ndarray,
    planes: list[Plane],
    thresh: float,
    min_inliers: int,
    normals: np.ndarray,
    min_spread: float = 0.5,
) -> Plane | None:
    """A smaller level below every level found (the floor of a bedroom seen past the bed), from the
    heights of all points along the known up: the lowest window of width 2 x `thresh` holding at least
    `min_inliers` points spread at least `min_spread` metres across, three times as many as the windows
    within 30 cm of it (a level is a spike in the heights), and whose sampled surface normals mostly
    point up (a wall or a table's front sliced at some height faces sideways). The big-plane search needs 8 % of
    the points; a floor strip under the furniture holds less, and without it nothing stands on it."""
    if not planes:
        return None
    h = -(P @ up)  # distance below the camera
    lowest = max(pl.d for pl in planes)
    cand = h > lowest + 0.10
    if cand.sum() < min_inliers:
        return None
    edges = np.arange(lowest + 0.10, float(h[cand].max()) + thresh, thresh)
    counts, _ = np.histogram(h[cand], bins=edges)
    win = counts[:-1] + counts[1:] if len(counts) > 1 else counts
    span = max(1, int(round(0.3 / thresh)))
    for k in np.flatnonzero(win >= min_inliers)[::-1]:  # lowest first
        around = np.r_[win[max(0, k - span) : max(0, k - 2)], win[k + 3 : k + 3 + span]]
        if around.size and win[k] < 3.0 * max(float(np.median(around)), 1.0):
            continue  # no spike: a vertical face sliced at some height, not a level
        lo, hi = edges[k], edges[min(k + 2, len(edges) - 1)]
        inl = np.flatnonzero((h >= lo) & (h < hi))
        d = float(np.median(h[inl]))
        inl = np.flatnonzero(np.abs(h - d) < thresh)
        flat = P[inl] - np.outer(P[inl] @ up, up)
        nv = normals[inl]
        nv = nv[np.all(np.isfinite(nv), axis=1)]
        level = np.abs(nv @ up) >= np.cos(np.deg2rad(10.0))
        # its points face up (a wall or a table front sliced at that height faces sideways)
        if (
            len(inl) >= min_inliers
            and np.ptp(flat, axis=0).max() >= min_spread
            and len(nv) >= 5
            and level.mean() >= 0.6
        ):
            return Plane(up, d, inl)
    return None


def refine_up(up: np.ndarray, planes: list[Plane], walls: list[Plane], max_dev_deg: float = 3.0) -> np.ndarray:
    """Gravity from every level and wall at once: the unit u minimising
    sum_h w_h |u - n_h|^2 + sum_w w_w (u . n_w)^2 (weights = inliers), i.e. the smallest eigenvector of
    sum_h w_h (I - n_h n_h^T) + sum_w w_w n_w n_w^T. A level or wall more than `max_dev_deg` off the
    first level's normal (horizontal, resp. vertical) is left out: a sloped cover or a leaning
    headboard is not the room. A wall seen over most of the picture fixes the tilt about its normal
    better than a small floor patch does (SUN RGB-D frames of a bed against a wall)."""
    up = np.asarray(up, float) / np.linalg.norm(up)
    M = np.zeros((3, 3))
    c = np.cos(np.deg2rad(max_dev_deg))
    for pl in planes:
        n = pl.n / np.linalg.norm(pl.n)
        if n @ up >= c:
            M += len(pl.inliers) * (np.eye(3) - np.outer(n, n))
    for w in walls:
        n = w.n / np.linalg.norm(w.n)
        if abs(n @ up) <= np.sin(np.deg2rad(max_dev_deg)):
            M += len(w.inliers) * np.outer(n, n)
    if not M.any():
        return up
    _, v = np.linalg.eigh(M)
    u = v[:, 0]
    return u if u @ up >= 0 else -u


def find_walls(
    points: np.ndarray,
    rng: np.random.Generator,
    up: np.ndarray,
    thresh: float,
    min_inliers: int,
    max_walls: int = 2,
    normals: np.ndarray | None = None,
) -> list[Plane]:
    """Up to `max_walls` large vertical planes (normal within 10 degrees of horizontal), largest first.
    Lifting removes their points from box-annotated objects (the wall behind a bed)."""
    from refspatial_gen.depth.planes import ransac_plane

    P = np.asarray(points, float)
    out: list[Plane] = []
    remaining = np.arange(len(P))
    for _ in range(max_walls):
        if len(remaining) < min_inliers:
            break
        best = ransac_plane(
            P[remaining], rng, thresh, None, vertical_to=up, normals=None if normals is None else normals[remaining]
        )
        if best is None or len(best.inliers) < min_inliers:
            break
        out.append(Plane(best.n, best.d, remaining[best.inliers]))
        remaining = np.delete(remaining, best.inliers)
    return out
