"""RANSAC for (near-)horizontal planes in a point cloud, used for gravity and for scale recovery.

Vectorised numpy RANSAC rather than open3d's `segment_plane`: it takes the run's numpy Generator (so a
frame is a pure function of its inputs and seed) and can restrict hypotheses to normals within a cone
around the prior "up" direction, which open3d cannot.

Hypotheses: random point triples, plus (with `normals`) one-point hypotheses, a point with its own
local surface normal. A triple lies on a plane holding a fraction f of the points with probability f^3
(0.7 % for a floor holding 19 % of a room): 256 triples then miss the floor about one time in six, and
a table or a slanted bed cover wins instead (a 22 degree gravity error measured on a SUN RGB-D frame).
A point-normal hypothesis lies on it with probability about f, so a few hundred find it every time.
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


def point_normals(points: np.ndarray, which: np.ndarray | None = None, k: int = 16) -> np.ndarray:
    """Unit surface normal (sign arbitrary) of the points indexed by `which` (default all): PCA of each
    one's k nearest neighbours. NaN elsewhere and where the neighbourhood is not a surface (too few
    points, or no clearly smallest direction)."""
    from scipy.spatial import cKDTree

    P = np.asarray(points, np.float64)
    out = np.full(P.shape, np.nan)
    if len(P) <= k:
        return out
    which = np.arange(len(P)) if which is None else np.asarray(which, np.int64)
    _, nb = cKDTree(P).query(P[which], k=k)
    Q = P[nb] - P[nb].mean(axis=1, keepdims=True)
    w, v = np.linalg.eigh(np.einsum("nki,nkj->nij", Q, Q))
    flat = w[:, 0] < 0.2 * w[:, 1]  # a plane-like patch: the smallest spread well below the others
    out[which[flat]] = v[flat, :, 0]
    return out


def ransac_plane(
    points: np.ndarray,
    rng: np.random.Generator,
    thresh: float,
    up: np.ndarray | None = None,
    max_tilt: float = np.deg2rad(40.0),
    iters: int = 256,
    score_points: int = 4000,
    vertical_to: np.ndarray | None = None,
    normals: np.ndarray | None = None,
) -> Plane | None:
    """Best plane (most inliers within `thresh`) whose normal lies within `max_tilt` of `up` (if given),
    or, with `vertical_to`, a vertical plane: normal within 10 degrees of perpendicular to that up.
    `normals` (per point, NaN = none; see `point_normals`) add `iters` one-point hypotheses."""
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
    if normals is not None:
        have = np.flatnonzero(np.all(np.isfinite(normals), axis=1))
        if len(have):
            pick = have[rng.integers(0, len(have), size=iters)]
            a = np.concatenate([a, P[pick]])
            n = np.concatenate([n, normals[pick]])
            ok = np.concatenate([ok, np.ones(len(pick), bool)])
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


def horizontal_planes(
    points: np.ndarray,
    rng: np.random.Generator,
    up: np.ndarray,
    thresh: float,
    min_inliers: int,
    max_planes: int = 3,
    max_tilt: float = np.deg2rad(40.0),
    normals: np.ndarray | None = None,
) -> list[Plane]:
    """Up to `max_planes` disjoint planes within `max_tilt` of `up`, each with >= `min_inliers` points,
    largest first. Later planes are required to be parallel to the first (within 10 degrees).
    `normals` (per point) seed one-point hypotheses (see the module docstring)."""
    P = np.asarray(points, np.float64)
    remaining = np.arange(len(P))
    planes: list[Plane] = []
    for _ in range(max_planes):
        if len(remaining) < min_inliers:
            break
        cone_up, tilt = (up, max_tilt) if not planes else (planes[0].n, np.deg2rad(10.0))
        pl = ransac_plane(
            P[remaining], rng, thresh, cone_up, tilt, normals=None if normals is None else normals[remaining]
        )
        if pl is None or len(pl.inliers) < min_inliers:
            break
        planes.append(Plane(pl.n, pl.d, remaining[pl.inliers]))
        remaining = np.delete(remaining, pl.inliers)
    return planes
