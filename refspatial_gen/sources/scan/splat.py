"""Depth from a point cloud by z-buffered splats (ScanNet ships posed colour frames and points, no depth).

Each point covers a square of about its neighbour spacing at its distance, so a sparse cloud still
gives a closed surface where it is dense enough, and the z-buffer keeps the nearest one: occlusion and
visibility follow from the same map as everywhere else.
"""

from __future__ import annotations

import numpy as np

from refspatial_gen.core.camera import Camera


def point_spacing(points: np.ndarray, sample: int = 4000) -> float:
    """Median nearest-neighbour distance of a cloud (metres), on a deterministic subsample."""
    from scipy.spatial import cKDTree

    pts = np.asarray(points, float)
    if len(pts) < 2:
        return 0.0
    step = max(1, len(pts) // sample)
    d, _ = cKDTree(pts).query(pts[::step], k=2)
    return float(np.median(d[:, 1]))


def splat_depth(
    points: np.ndarray,
    cam: Camera,
    spacing: float,
    scale: float = 0.75,
    max_radius: int = 12,
    near: float = 0.05,
    with_owner: bool = False,
):
    """World points -> float32 z-depth map (0 = no point). Splat half-size = scale * spacing * f / z pixels.
    With `with_owner`, also the (H, W) int64 index of the point each pixel shows (-1 = none): per-point
    instance labels project into the frame through it, with the same z-buffer as the depth."""
    H, W = cam.height, cam.width
    pc = cam.world_to_cam(points)
    z = pc[:, 2]
    keep = z > near
    pc, z = pc[keep], z[keep]
    uv, _ = cam.project_cam(pc)
    u = np.floor(uv[:, 0]).astype(np.int64)
    v = np.floor(uv[:, 1]).astype(np.int64)
    f = 0.5 * (cam.fx + cam.fy)
    r = np.clip(np.round(scale * spacing * f / z), 0, max_radius).astype(np.int64)
    ok = (u >= -max_radius) & (u < W + max_radius) & (v >= -max_radius) & (v < H + max_radius)
    u, v, z, r = u[ok], v[ok], z[ok], r[ok]
    pid = np.flatnonzero(keep)[ok]
    idx_all, z_all, p_all = [], [], []
    for rad in np.unique(r):
        sel = r == rad
        off = np.arange(-rad, rad + 1)
        du, dv = np.meshgrid(off, off)
        uu = (u[sel][:, None] + du.ravel()[None]).ravel()
        vv = (v[sel][:, None] + dv.ravel()[None]).ravel()
        zz = np.repeat(z[sel], du.size)
        inside = (uu >= 0) & (uu < W) & (vv >= 0) & (vv < H)
        idx_all.append(vv[inside] * W + uu[inside])
        z_all.append(zz[inside])
        p_all.append(np.repeat(pid[sel], du.size)[inside])
    depth = np.zeros(H * W, np.float32)
    owner = np.full(H * W, -1, np.int64)
    if idx_all:
        idx = np.concatenate(idx_all)
        zs = np.concatenate(z_all)
        ps = np.concatenate(p_all)
        order = np.lexsort((ps, zs, idx))  # nearest first; ties to the lower point index (deterministic)
        idx, zs, ps = idx[order], zs[order], ps[order]
        first = np.ones(idx.size, bool)
        first[1:] = idx[1:] != idx[:-1]
        depth[idx[first]] = zs[first]
        owner[idx[first]] = ps[first]
    if with_owner:
        return depth.reshape(H, W), owner.reshape(H, W)
    return depth.reshape(H, W)
