"""Lifting one 2D object to a gravity-aligned 3D box from its mask and a metric depth map.

mask pixels with depth -> world points -> (drop points lying on a support plane under the object or
on a wall, when they are a minority) -> depth-continuous components in the image (a neighbour jump of
more than max(5 cm, 3% of depth) separates surfaces; unlike a 3D DBSCAN on subsampled points this keeps
a mattress seen at a grazing angle in one piece) -> keep the largest (box annotations: weighted to the
box centre) -> subsample -> statistical outlier removal (open3d) -> DBSCAN (open3d), keep the largest
cluster -> yaw from the minimum-area rectangle of the footprint, z from robust percentiles ->
optional snapping of the bottom to a support plane just below -> optional amodal completion: a single
view sees only the front surface, so the extent along the viewing direction is grown (away from the
camera) to min(width across, height), a documented shape prior.
Box annotations with measured depth arrive `preselected` (their pixels cut by boxseg.py): plane removal,
component choice and DBSCAN are skipped, and source.py completes them with amodal.py.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from refspatial_gen.core.geometry import Box3D, rot_z


@dataclass(frozen=True)
class LiftParams:
    max_points: int = 1500
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
    keep_pixels: np.ndarray  # bool over the input pixels: the ones on the kept surface
    notes: dict
    visible_box: Box3D | None = None  # before amodal completion


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
    return Box3D(
        np.array([center_xy[0], center_xy[1], (z0 + z1) / 2]), np.array([sx, sy, max(z1 - z0, 0.0)]), rot_z(yaw)
    )


def complete_along_view(box: Box3D, cam_xy: np.ndarray) -> tuple[Box3D, float]:
    """Grow the box's thinner horizontal extent (the visible surface's normal) to min(other width,
    height), away from the camera."""
    v = box.center[:2] - cam_xy
    if np.linalg.norm(v) < 1e-9:
        return box, 0.0
    v = v / np.linalg.norm(v)
    depth_axis = 0 if box.size[0] <= box.size[1] else 1
    axis_vec = box.rotation[:2, depth_axis]
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


def depth_components(zc: np.ndarray, rel_jump: float = 0.03, abs_jump: float = 0.05) -> np.ndarray:
    """Label image regions of continuous depth (`zc` a crop, 0 = excluded); pixels at a jump get 0."""
    import cv2

    valid = zc > 0
    thr = np.maximum(abs_jump, rel_jump * zc)
    edge = np.zeros_like(valid)
    jx = valid[:, 1:] & valid[:, :-1] & (np.abs(np.diff(zc, axis=1)) > np.minimum(thr[:, 1:], thr[:, :-1]))
    jy = valid[1:, :] & valid[:-1, :] & (np.abs(np.diff(zc, axis=0)) > np.minimum(thr[1:, :], thr[:-1, :]))
    edge[:, 1:] |= jx
    edge[:, :-1] |= jx
    edge[1:, :] |= jy
    edge[:-1, :] |= jy
    _, labels = cv2.connectedComponents((valid & ~edge).astype(np.uint8), connectivity=4)
    return labels


def lift_object(
    xs: np.ndarray,
    ys: np.ndarray,
    zz: np.ndarray,
    cam,
    params: LiftParams,
    support_z: list[float] | None = None,
    walls: list[tuple[np.ndarray, float]] | None = None,
    weights: np.ndarray | None = None,
    preselected: bool = False,
) -> Lifted | str:
    """All valid-depth pixels of one object (x, y, z-depth) -> Lifted, or a drop reason string.

    `preselected`: the pixels are already the object's surfaces (box annotations cut by
    boxseg.assign_boxes): no plane removal, and every depth component is kept.
    `keep_pixels` of the result indexes these pixels (the ones on the kept surface)."""
    world = cam.cam_to_world(cam.backproject(xs + 0.5, ys + 0.5, zz))  # pixel centres
    n_in = len(zz)
    keep = np.ones(n_in, bool)
    notes: dict = {}
    if support_z and not preselected:
        on_plane = np.zeros(n_in, bool)
        for z in support_z:
            # only a plane at the object's bottom (floor under a chair, bed top under a pillow); a plane
            # with much of the object below it is the object's own top (the bed's mattress)
            if np.mean(world[:, 2] < z - params.plane_band) <= 0.1:
                on_plane |= np.abs(world[:, 2] - z) < params.plane_band
        if 0 < on_plane.sum() < 0.6 * n_in:  # a majority on the plane means the object *is* the surface
            keep &= ~on_plane
            notes["plane_points_removed"] = int(on_plane.sum())
    for n, d in [] if preselected else walls or []:
        on_wall = keep & (np.abs(world @ n + d) < params.plane_band)
        if 0 < on_wall.sum() < 0.5 * keep.sum():
            keep &= ~on_wall
            notes["wall_points_removed"] = notes.get("wall_points_removed", 0) + int(on_wall.sum())
    if keep.sum() < params.min_points:
        return "low_valid_depth"
    x0, y0 = int(xs.min()), int(ys.min())
    zc = np.zeros((int(ys.max()) - y0 + 1, int(xs.max()) - x0 + 1), np.float32)
    zc[ys[keep] - y0, xs[keep] - x0] = zz[keep]
    lab = depth_components(zc)[ys - y0, xs - x0]
    lab[~keep] = 0
    if lab.max() == 0:
        return "no_cluster"
    w = np.ones(n_in) if weights is None else np.asarray(weights, float)
    score = np.bincount(lab, weights=w)
    score[0] = 0
    comp = lab > 0 if preselected else lab == int(np.argmax(score))
    notes["components"] = int(np.count_nonzero(np.bincount(lab)[1:]))
    idx_all = np.flatnonzero(comp)
    if len(idx_all) < params.min_points:
        return "no_cluster"
    step = max(1, int(np.ceil(np.sqrt(len(idx_all) / params.max_points))))
    sub = idx_all[(xs[idx_all] % step == 0) & (ys[idx_all] % step == 0)]
    if len(sub) < params.min_points:
        sub = idx_all
        step = 1
    pix_scale = float(np.median(zz[sub])) / cam.fx * step
    out = lift_points(world[sub], pix_scale, params, cluster=not preselected)
    if isinstance(out, str):
        return out
    out.notes = {**notes, **out.notes}
    if support_z and params.snap_distance > 0:
        out.box, snapped = snap_to_support(out.box, support_z, params)
        if snapped is not None:
            out.notes["snapped_to_support"] = snapped
    out.visible_box = out.box
    if params.complete_depth:
        out.box, grow = complete_along_view(out.box, cam.position[:2])
        if grow > 0:
            out.notes["depth_completed"] = round(grow, 4)
    if np.any(out.box.size > params.max_size) or out.box.size.max() <= 0:
        return "implausible_size"
    keep_px = np.zeros(n_in, bool)
    keep_px[idx_all] = True
    out.keep_pixels = keep_px
    out.cluster_fraction = float(len(idx_all) / max(n_in, 1))
    return out


def snap_to_support(box: Box3D, support_z: list[float], params: LiftParams) -> tuple[Box3D, float | None]:
    """Extend the box down to a support plane at most `snap_distance` below its bottom (occluded bottoms)."""
    below = [z for z in support_z if -params.plane_band <= box.bottom_z - z <= params.snap_distance]
    if not below:
        return box, None
    z = max(below)
    top = box.top_z
    if top <= z:
        return box, None
    c = box.center.copy()
    c[2] = (top + z) / 2
    s = box.size.copy()
    s[2] = top - z
    return Box3D(c, s, box.rotation), round(float(box.bottom_z - z), 4)


def lift_points(world: np.ndarray, pixel_scale: float, params: LiftParams, cluster: bool = True) -> Lifted | str:
    """Subsampled world points of one surface -> outlier removal, largest DBSCAN cluster, upright box.

    `pixel_scale` is metres between neighbouring points at the median depth (DBSCAN's eps is 3x it).
    `cluster=False`: the points were segmented already (box layering); only outliers are removed (a
    subsampled surface seen at a grazing angle is sparser than eps and DBSCAN would cut it up)."""
    n_in = len(world)
    idx = np.arange(n_in)
    if n_in < params.min_points:
        return "low_valid_depth"
    pc = _o3d_cloud(world)
    if n_in > params.outlier_neighbours + 1:
        _, ind = pc.remove_statistical_outlier(params.outlier_neighbours, params.outlier_std)
        ind = np.asarray(ind, dtype=np.int64)
        idx = idx[ind]
        pc = pc.select_by_index(ind.tolist())
    if len(idx) < params.min_points:
        return "low_valid_depth"
    if not cluster:
        keep_px = np.zeros(n_in, bool)
        keep_px[idx] = True
        return Lifted(fit_upright_box(world[idx]), int(len(idx)), float(len(idx) / n_in), keep_px, {"clusters": 0})
    eps = float(max(0.03, 3.0 * pixel_scale))
    labels = np.asarray(pc.cluster_dbscan(eps=eps, min_points=params.dbscan_min_points, print_progress=False))
    if labels.size == 0 or labels.max() < 0:
        return "no_cluster"
    counts = np.bincount(labels[labels >= 0])
    # the surface is already one depth-continuous component: DBSCAN only sheds floaters, so every
    # cluster holding at least 3% of the points is kept (a surface seen at a grazing angle splits)
    major = np.flatnonzero(counts >= max(params.dbscan_min_points, 0.03 * len(idx)))
    if major.size == 0:
        major = np.array([int(np.argmax(counts))])
    idx = idx[np.isin(labels, major)]
    if len(idx) < params.min_points:
        return "no_cluster"
    box = fit_upright_box(world[idx])
    keep_px = np.zeros(n_in, bool)
    keep_px[idx] = True
    return Lifted(box, int(len(idx)), float(len(idx) / n_in), keep_px, {"clusters": int(len(counts))})
