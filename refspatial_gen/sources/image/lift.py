"""Lifting one 2D object to a gravity-aligned 3D box from its mask and a metric depth map.

mask pixels with depth -> camera points -> world points -> (drop points lying on a support plane when
they are a minority) -> statistical outlier removal (open3d) -> DBSCAN (open3d), keep the largest
cluster -> yaw from the minimum-area rectangle of the footprint, z from robust percentiles ->
optional snapping of the bottom to a support plane just below -> optional amodal completion: a single
view sees only the front surface, so the extent along the viewing direction is grown (away from the
camera) to min(width across, height), a documented shape prior.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from refspatial_gen.core.geometry import Box3D, rot_z


@dataclass(frozen=True)
class LiftParams:
    max_points: int = 2500
    min_points: int = 30
    min_valid_fraction: float = 0.3
    outlier_neighbours: int = 16
    outlier_std: float = 2.0
    dbscan_min_points: int = 8
    plane_band: float = 0.03  # points within this of a support plane belong to the plane
    snap_distance: float = 0.25  # bottom snaps down to a support plane at most this far below
    complete_depth: bool = True
    max_size: float = 30.0


@dataclass
class Lifted:
    box: Box3D
    points_used: int
    cluster_fraction: float
    keep_pixels: np.ndarray  # bool over the input pixels: the ones whose point ended in the kept cluster
    notes: dict


def _o3d_cloud(points: np.ndarray):
    import open3d as o3d

    return o3d.geometry.PointCloud(o3d.utility.Vector3dVector(np.ascontiguousarray(points, dtype=np.float64)))


def fit_upright_box(pts: np.ndarray) -> Box3D:
    """Gravity-aligned box: minimum-area rectangle of the xy footprint, z from 1st-99th percentiles."""
    import cv2

    z0, z1 = np.percentile(pts[:, 2], [1.0, 99.0])
    xy = pts[:, :2]
    if len(xy) >= 3 and np.ptp(xy, axis=0).max() > 1e-6:
        (cx, cy), (w, h), ang = cv2.minAreaRect(xy.astype(np.float32))
        yaw = np.deg2rad(ang)
        # minAreaRect works in float32: recompute extents exactly in float64 along its axes
        R2 = np.array([[np.cos(yaw), -np.sin(yaw)], [np.sin(yaw), np.cos(yaw)]])
        loc = xy @ R2
        lo, hi = loc.min(axis=0), loc.max(axis=0)
        c_loc = (lo + hi) / 2
        center_xy = R2 @ c_loc
        sx, sy = hi - lo
    else:
        yaw, center_xy, sx, sy = 0.0, xy.mean(axis=0), 0.0, 0.0
    return Box3D(np.array([center_xy[0], center_xy[1], (z0 + z1) / 2]), np.array([sx, sy, max(z1 - z0, 0.0)]), rot_z(yaw))


def complete_along_view(box: Box3D, cam_xy: np.ndarray) -> tuple[Box3D, float]:
    """Grow the box's extent along the horizontal viewing direction to min(across width, height)."""
    v = box.center[:2] - cam_xy
    if np.linalg.norm(v) < 1e-9:
        return box, 0.0
    v = v / np.linalg.norm(v)
    ax = box.rotation[:2, 0]
    ay = box.rotation[:2, 1]
    depth_axis = 0 if abs(ax @ v) >= abs(ay @ v) else 1
    axis_vec = ax if depth_axis == 0 else ay
    across = box.size[1 - depth_axis]
    target = min(across, box.size[2])
    grow = target - box.size[depth_axis]
    if grow <= 0:
        return box, 0.0
    size = box.size.copy()
    size[depth_axis] = target
    sign = 1.0 if axis_vec @ v >= 0 else -1.0
    c = box.center.copy()
    c[:2] += sign * axis_vec * grow / 2
    return Box3D(c, size, box.rotation), float(grow)


def lift_points(world: np.ndarray, cam_xy: np.ndarray, pixel_scale: float, params: LiftParams,
                support_z: list[float] | None = None) -> Lifted | str:
    """World points of one object's pixels (already subsampled) -> Lifted, or a drop reason string.

    `pixel_scale` is metres per pixel at the median depth (times the subsampling step), for DBSCAN's eps;
    `support_z` are heights of known horizontal support planes (world z)."""
    n_in = len(world)
    keep = np.ones(n_in, bool)
    notes: dict = {}
    if support_z:
        on_plane = np.zeros(n_in, bool)
        for z in support_z:
            on_plane |= np.abs(world[:, 2] - z) < params.plane_band
        if 0 < on_plane.sum() < 0.6 * n_in:  # a majority on the plane means the object *is* the surface
            keep &= ~on_plane
            notes["plane_points_removed"] = int(on_plane.sum())
    idx = np.flatnonzero(keep)
    if len(idx) < params.min_points:
        return "low_valid_depth"
    pc = _o3d_cloud(world[idx])
    if len(idx) > params.outlier_neighbours + 1:
        _, ind = pc.remove_statistical_outlier(params.outlier_neighbours, params.outlier_std)
        ind = np.asarray(ind, dtype=np.int64)
        idx = idx[ind]
        pc = pc.select_by_index(ind.tolist())
    if len(idx) < params.min_points:
        return "low_valid_depth"
    eps = float(max(0.03, 3.0 * pixel_scale))
    labels = np.asarray(pc.cluster_dbscan(eps=eps, min_points=params.dbscan_min_points, print_progress=False))
    if labels.size == 0 or labels.max() < 0:
        return "no_cluster"
    counts = np.bincount(labels[labels >= 0])
    main = int(np.argmax(counts))
    idx = idx[labels == main]
    notes["clusters"] = int(len(counts))
    if len(idx) < params.min_points:
        return "no_cluster"
    pts = world[idx]
    box = fit_upright_box(pts)
    if support_z and params.snap_distance > 0:
        below = [z for z in support_z if -params.plane_band <= box.bottom_z - z <= params.snap_distance]
        if below:
            z = max(below)
            top = box.top_z
            if top > z:
                c = box.center.copy()
                c[2] = (top + z) / 2
                s = box.size.copy()
                s[2] = top - z
                notes["snapped_to_support"] = round(float(box.bottom_z - z), 4)
                box = Box3D(c, s, box.rotation)
    if params.complete_depth:
        box, grow = complete_along_view(box, cam_xy)
        if grow > 0:
            notes["depth_completed"] = round(grow, 4)
    if np.any(box.size > params.max_size) or box.size.max() <= 0:
        return "implausible_size"
    keep_px = np.zeros(n_in, bool)
    keep_px[idx] = True
    return Lifted(box, int(len(idx)), float(len(idx) / max(n_in, 1)), keep_px, notes)
