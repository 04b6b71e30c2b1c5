"""RANSAC for (near-)horizontal planes in a point cloud, used for gravity and for scale recovery.

Vectorised numpy RANSAC rather than open3d's `segment_plane`: it takes the run's numpy Generator (so a
frame is a pure function of its inputs and seed) and can restrict hypotheses to normals within a cone
around the prior "up" direction, which open3d cannot.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np


@dataclass
class Plane:
    """n . p + d = 0 with unit normal `n` oriented towards the prior up; `inliers` indexes the input."""

    n: np.ndarray
    d: float
    inliers: np.ndarray

    def signed_distance(self, points: np.ndarray) -> np.ndarray:
        return points @ self.n + self.d


def ransac_plane(points: np.ndarray, rng: np.random.Generator, thresh: float, up: np.ndarray | None = None,
                 max_tilt: float = np.deg2rad(40.0), iters: int = 256, score_points: int = 4000,
                 vertical_to: np.ndarray | None = None) -> Plane | None:
    """Best plane (most inliers within `thresh`) whose normal lies within `max_tilt` of `up` (if given),
    or, with `vertical_to`, a vertical plane: normal within 10 degrees of perpendicular to that up."""
    P = np.asarray(points, np.float64)
    N = len(P)
    if N < 3:
        return None
    idx = rng.integers(0, N, size=(iters, 3))
    a, b, c = P[idx[:, 0]], P[idx[:, 1]], P[idx[:, 2]]
    n = np.cross(b - a, c - a)
    norm = np.linalg.norm(n, axis=1)
    ok = norm > 1e-12
    n = n / np.where(ok, norm, 1.0)[:, None]
    if up is not None:
        s = np.sign(n @ up)
        n = n * np.where(s == 0, 1.0, s)[:, None]
        ok &= (n @ up) >= np.cos(max_tilt)
    if vertical_to is not None:
        ok &= np.abs(n @ vertical_to) <= np.sin(np.deg2rad(10.0))
    if not ok.any():
        return None
    n, a = n[ok], a[ok]
    d = -np.einsum("ij,ij->i", n, a)
    S = P if N <= score_points else P[rng.choice(N, score_points, replace=False)]
    counts = (np.abs(S @ n.T + d) < thresh).sum(axis=0)
    k = int(np.argmax(counts))
    best_n, best_d = n[k], d[k]
    for _ in range(2):  # refit on inliers (least squares), then re-select
        inl = np.abs(P @ best_n + best_d) < thresh
        if inl.sum() < 3:
            return None
        Q = P[inl]
        c0 = Q.mean(axis=0)
        _, _, vt = np.linalg.svd(Q - c0, full_matrices=False)
        nn = vt[2]
        if up is not None and nn @ up < 0:
            nn = -nn
        best_n, best_d = nn, float(-nn @ c0)
    if up is not None and best_n @ up < np.cos(max_tilt):
        return None
    if vertical_to is not None and abs(best_n @ vertical_to) > np.sin(np.deg2rad(10.0)):
        return None
    inl = np.flatnonzero(np.abs(P @ best_n + best_d) < thresh)
    return Plane(best_n, float(best_d), inl)


def horizontal_planes(points: np.ndarray, rng: np.random.Generator, up: np.ndarray, thresh: float,
                      min_inliers: int, max_planes: int = 3, max_tilt: float = np.deg2rad(40.0)) -> list[Plane]:
    """Up to `max_planes` disjoint planes within `max_tilt` of `up`, each with >= `min_inliers` points,
    largest first. Later planes are required to be parallel to the first (within 10 degrees)."""
    P = np.asarray(points, np.float64)
    remaining = np.arange(len(P))
    planes: list[Plane] = []
    for _ in range(max_planes):
        if len(remaining) < min_inliers:
            break
        cone_up, tilt = (up, max_tilt) if not planes else (planes[0].n, np.deg2rad(10.0))
        pl = ransac_plane(P[remaining], rng, thresh, cone_up, tilt)
        if pl is None or len(pl.inliers) < min_inliers:
            break
        planes.append(Plane(pl.n, pl.d, remaining[pl.inliers]))
        remaining = np.delete(remaining, pl.inliers)
    return planes
