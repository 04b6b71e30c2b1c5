"""Per-object visibility in a scan view: which pixels inside an object box's silhouette show the object.

Visibility rule (the same for every reader): a pixel inside the silhouette of an object's box is
  * visible (in the mask) when the depth map's 3D point lies inside the box (lightly padded, the bottom
    `floor_margin` (at most a quarter of the box height) trimmed so the floor under a table is not "table");
  * occluded when the depth map is more than `occlusion_tolerance` (2.5 cm) nearer than where the ray
    enters the box;
  * see-through otherwise (the box is loose there: background behind a chair's legs).
The visible fraction is visible / (visible + occluded pixels that the object would fill), times the
part of the box that projects inside the image. When the reader gives a point cloud (ScanNet), the
fraction is instead the share of the object's own points that are in the image and not hidden by
something outside the box (hidden behind the object's own surface does not count as occluded).
"""

from __future__ import annotations

from typing import Any

import numpy as np

from refspatial_gen.core.camera import Camera
from refspatial_gen.core.geometry import Box3D


def pixel_rays(cam: Camera, x0: int, y0: int, x1: int, y1: int) -> np.ndarray:
    """Camera-frame ray directions with z = 1 through the pixel centres of a window, shape (h, w, 3)."""
    vs, us = np.mgrid[y0:y1, x0:x1]
    return np.stack([(us + 0.5 - cam.cx) / cam.fx, (vs + 0.5 - cam.cy) / cam.fy, np.ones(us.shape)], axis=-1)


def box_window(cam: Camera, box: Box3D) -> tuple[int, int, int, int] | None:
    """Image window covering the box's projection (whole image when a corner is behind the camera)."""
    pc = cam.world_to_cam(box.corners())
    if np.all(pc[:, 2] <= 1e-6):
        return None
    if np.any(pc[:, 2] <= 1e-6):
        return 0, 0, cam.width, cam.height
    uv, _ = cam.project_cam(pc)
    x0, y0 = np.floor(uv.min(axis=0)).astype(int)
    x1, y1 = np.ceil(uv.max(axis=0)).astype(int) + 1
    x0, y0, x1, y1 = max(0, x0), max(0, y0), min(cam.width, x1), min(cam.height, y1)
    if x0 >= x1 or y0 >= y1:
        return None
    return int(x0), int(y0), int(x1), int(y1)


def in_image_fraction(cam: Camera, box: Box3D) -> float:
    """Share of the box volume (grid samples) in front of the camera and inside the image."""
    uv, z = cam.project(box.grid_points(8))
    ok = (z > 1e-6) & (uv[:, 0] >= 0) & (uv[:, 0] < cam.width) & (uv[:, 1] >= 0) & (uv[:, 1] < cam.height)
    return float(ok.mean())


def in_image_share(cam: Camera, box: Box3D, sil_pixels_in_image: int) -> float:
    """Share of the box's silhouette that falls inside the image: exact (pixel count over the projected
    hull's area) when the box is fully in front of the camera, else the volume-sample estimate, never
    below one sample (1/512) when some of it is in the image."""
    import cv2

    pc = cam.world_to_cam(box.corners())
    if np.all(pc[:, 2] > 1e-6):
        uv, _ = cam.project_cam(pc)
        hull = cv2.convexHull(uv.astype(np.float32))
        area = float(cv2.contourArea(hull))
        if area > 0:
            return float(min(1.0, sil_pixels_in_image / area))
    share = in_image_fraction(cam, box)
    return max(share, 1.0 / 512) if sil_pixels_in_image > 0 else share


def inside_box(
    local: np.ndarray, size: np.ndarray, pad: float, bottom_trim: float, world_z: np.ndarray, bottom_z: float
) -> np.ndarray:
    """Points (in box coordinates) inside the padded box, minus a slab just above the box's lowest point."""
    ok = np.all(np.abs(local) <= size / 2.0 + pad, axis=-1)
    if bottom_trim > 0:
        ok &= world_z > bottom_z + bottom_trim
    return ok


def close_unknown(mask: np.ndarray, unknown: np.ndarray) -> np.ndarray:
    """Fill 1-2 pixel holes of a mask where the depth is unknown (sensor speckle), never over known depth."""
    import cv2

    if not mask.any():
        return mask
    closed = cv2.morphologyEx(mask.astype(np.uint8), cv2.MORPH_CLOSE, np.ones((3, 3), np.uint8)).astype(bool)
    return mask | (closed & unknown)


def object_visibility(
    cam: Camera,
    depth: np.ndarray,
    box: Box3D,
    tol: float,
    pad: float,
    floor_margin: float,
    gravity_known: bool,
    points: np.ndarray | None = None,
    splat_extent: float = 0.0,
) -> dict[str, Any] | None:
    """Visible mask and counts for one box; None when its projection misses the image. `tol` is the
    occlusion tolerance, `pad` the mask padding, `floor_margin` the bottom slab trimmed (metres).

    `splat_extent` (metres) is the half-size of the splats when `depth` was splatted from `points`."""
    win = box_window(cam, box)
    if win is None:
        return None
    x0, y0, x1, y1 = win
    # never trim more than a quarter of a flat object's height (a tray is 2-3 cm tall)
    trim = min(floor_margin, 0.25 * box.height) if gravity_known else 0.0
    rays = pixel_rays(cam, x0, y0, x1, y1)
    R, o = cam.world_from_cam[:3, :3], cam.world_from_cam[:3, 3]
    d_world = rays @ R.T  # world direction per pixel, scaled so camera z = 1
    ol = (o - box.center) @ box.rotation
    dl = d_world @ box.rotation
    half = box.size / 2.0
    with np.errstate(divide="ignore", invalid="ignore"):
        t1 = (-half - ol) / dl
        t2 = (half - ol) / dl
    t_in = np.nanmax(np.minimum(t1, t2), axis=-1)
    t_out = np.nanmin(np.maximum(t1, t2), axis=-1)
    sil = (t_in <= t_out) & (t_out > 1e-6)
    t_in = np.maximum(t_in, 0.0)
    d = depth[y0:y1, x0:x1].astype(np.float64)
    valid = sil & (d > 0)
    p_world = o + d_world * d[..., None]
    local = (p_world - box.center) @ box.rotation
    bottom = box.bottom_z
    inside = valid & inside_box(local, box.size, pad, trim, p_world[..., 2], bottom)
    occluded = valid & ~inside & (d < t_in - tol)
    through = valid & ~inside & ~occluded
    inside = close_unknown(inside, sil & (d <= 0))
    mask = np.zeros((cam.height, cam.width), bool)
    mask[y0:y1, x0:x1] = inside
    claim = np.zeros_like(mask)  # pixels on this object even if trimmed from its mask (its bottom slab)
    claim[y0:y1, x0:x1] = inside | (valid & inside_box(local, box.size, pad, 0.0, p_world[..., 2], bottom))
    n_in, n_occ, n_thr = int(inside.sum()), int(occluded.sum()), int(through.sum())
    fill = n_in / (n_in + n_thr) if n_in + n_thr else 0.0
    frac_unoccluded = n_in / (n_in + fill * n_occ) if n_in else 0.0
    visible_fraction = frac_unoccluded * in_image_share(cam, box, int(sil.sum()))
    out = {
        "mask": mask,
        "claim": claim,
        "visible_pixels": n_in,
        "occluded_pixels": n_occ,
        "see_through_pixels": n_thr,
        "visible_fraction": visible_fraction,
        "fraction_method": "depth_pixels",
    }
    if points is not None:
        _point_fraction(out, cam, depth, box, points, pad, trim, tol, splat_extent)
    return out


def _point_fraction(
    out: dict[str, Any],
    cam: Camera,
    depth: np.ndarray,
    box: Box3D,
    points: np.ndarray,
    pad: float,
    trim: float,
    tol: float,
    splat_extent: float,
) -> None:
    """With a point cloud: the visible fraction is the share of the object's own points in the image and not
    hidden by something outside the box (updates `out` in place)."""
    bottom = box.bottom_z
    lp = box.to_local(points)
    own = points[inside_box(lp, box.size, pad, trim, points[:, 2], bottom)]
    if len(own) >= 10:
        uv, z = cam.project(own)
        ok = (z > 1e-6) & (uv[:, 0] >= 0) & (uv[:, 0] < cam.width) & (uv[:, 1] >= 0) & (uv[:, 1] < cam.height)
        u = np.floor(uv[ok, 0]).astype(int)
        v = np.floor(uv[ok, 1]).astype(int)
        dz = depth[v, u]
        # a splatted map is the nearest of overlapping splats: a point's own surface can read up to
        # one splat extent nearer on slanted surfaces, so the tolerance grows by that much
        seen = (dz > 0) & (z[ok] <= dz + tol + splat_extent)
        # hidden behind the object's own surface (a table's underside) is self-occlusion, not occlusion
        near_world = cam.cam_to_world(cam.backproject(u + 0.5, v + 0.5, dz))
        self_hidden = (dz > 0) & box.contains(near_world, pad)
        seen |= self_hidden
        if seen.any():  # else the mask rests on other points than the object's own: keep the pixel estimate
            out["visible_fraction"] = float(seen.sum()) / len(own)
            out["fraction_method"] = "object_points"
        out["object_points"] = int(len(own))
