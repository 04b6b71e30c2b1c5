"""ScanView -> Frame: frame checks, keyframe tests, per-object visibility, masks and support surfaces.

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
from refspatial_gen.core.errors import DropUnit
from refspatial_gen.core.geometry import Box3D
from refspatial_gen.core.mask import RLE
from refspatial_gen.core.model import Frame, ObjectInstance, SupportSurface
from refspatial_gen.sources.scan.gravity import fit_floor
from refspatial_gen.sources.scan.splat import point_spacing, splat_depth
from refspatial_gen.sources.scan.view import ScanBox, ScanView

DEFAULTS: dict[str, Any] = {
    "occlusion_tolerance": 0.025, "mask_pad": 0.01, "floor_margin": 0.03, "min_mask_pixels": 16,
    "min_visible_fraction": 0.0, "min_visible_objects": 1, "blur_threshold": 0.0, "max_width": 0,
    "splat_scale": 1.0, "instance_labels": True, "withhold_unexplained_floor": True, "unexplained_min_points": 20,
}

SUPPORT_KINDS = {
    "table": "table", "desk": "table", "coffee table": "table", "dining table": "table", "side table": "table",
    "counter": "counter", "bookshelf": "shelf", "shelf": "shelf", "night stand": "object", "dresser": "object",
    "cabinet": "object", "bed": "object", "ottoman": "object",
}
CATEGORY_NAMES = {"garbagebin": "garbage bin", "showercurtrain": "shower curtain", "night_stand": "night stand",
                  "refridgerator": "refrigerator"}


def category_phrase(raw: str) -> str:
    """Annotation class name -> the words used in text ("night_stand" -> "night stand")."""
    c = raw.strip().lower()
    return CATEGORY_NAMES.get(c, c.replace("_", " "))


def cfg(config: dict[str, Any], key: str) -> Any:
    v = config.get(key)
    return DEFAULTS[key] if v is None else v


def blur_score(rgb: np.ndarray) -> float:
    """Variance of the Laplacian of the grey image: low means blurred (motion blur, defocus)."""
    import cv2

    grey = cv2.cvtColor(rgb, cv2.COLOR_RGB2GRAY)
    return float(cv2.Laplacian(grey, cv2.CV_64F).var())


def check_pose(cam: Camera) -> None:
    T = cam.world_from_cam
    if not np.all(np.isfinite(T)):
        raise DropUnit("pose_invalid", "camera pose has NaN or infinite entries")
    R = T[:3, :3]
    if abs(np.linalg.det(R) - 1) > 1e-3 or not np.allclose(R.T @ R, np.eye(3), atol=1e-3) or not np.allclose(T[3], [0, 0, 0, 1]):
        raise DropUnit("pose_invalid", "camera pose is not a rigid transform")
    for name in ("fx", "fy", "cx", "cy"):
        if not np.isfinite(getattr(cam, name)) or (name in ("fx", "fy") and getattr(cam, name) <= 0):
            raise DropUnit("intrinsics_invalid", f"{name}={getattr(cam, name)}")


def check_depth(depth: np.ndarray, shape: tuple[int, int]) -> None:
    if depth.shape != shape:
        raise DropUnit("depth_size_mismatch", f"depth {depth.shape} vs image {shape}")
    if not np.all(np.isfinite(depth)):
        raise DropUnit("depth_nan", f"{int((~np.isfinite(depth)).sum())} NaN/inf depth pixels")
    if np.any(depth < 0):
        raise DropUnit("depth_negative", f"{int((depth < 0).sum())} negative depth pixels")
    if not np.any(depth > 0):
        raise DropUnit("depth_empty", "depth map has no valid pixel")


def resize_view(rgb: np.ndarray, depth: np.ndarray | None, cam: Camera, max_width: int) -> tuple[np.ndarray, np.ndarray | None, Camera]:
    """Downscale wide images (and K, corner-origin pixel convention) so masks and splats stay cheap."""
    import cv2

    if not max_width or cam.width <= max_width:
        return rgb, depth, cam
    s = max_width / cam.width
    W, H = int(max_width), int(round(cam.height * s))
    sx, sy = W / cam.width, H / cam.height
    rgb2 = cv2.resize(rgb, (W, H), interpolation=cv2.INTER_AREA)
    d2 = None if depth is None else cv2.resize(depth, (W, H), interpolation=cv2.INTER_NEAREST)
    cam2 = Camera(W, H, cam.fx * sx, cam.fy * sy, cam.cx * sx, cam.cy * sy, cam.world_from_cam, cam.gravity_known)
    return rgb2, d2, cam2


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


def inside_box(local: np.ndarray, size: np.ndarray, pad: float, bottom_trim: float, world_z: np.ndarray,
               bottom_z: float) -> np.ndarray:
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


def object_visibility(cam: Camera, depth: np.ndarray, box: Box3D, config: dict[str, Any],
                      gravity_known: bool, points: np.ndarray | None = None,
                      splat_extent: float = 0.0) -> dict[str, Any] | None:
    """Visible mask and counts for one box; None when its projection misses the image.

    `splat_extent` (metres) is the half-size of the splats when `depth` was splatted from `points`."""
    win = box_window(cam, box)
    if win is None:
        return None
    x0, y0, x1, y1 = win
    tol = float(cfg(config, "occlusion_tolerance"))
    pad = float(cfg(config, "mask_pad"))
    # never trim more than a quarter of a flat object's height (a tray is 2-3 cm tall)
    trim = min(float(cfg(config, "floor_margin")), 0.25 * box.height) if gravity_known else 0.0
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
    out = {"mask": mask, "claim": claim, "visible_pixels": n_in, "occluded_pixels": n_occ, "see_through_pixels": n_thr,
           "visible_fraction": visible_fraction, "fraction_method": "depth_pixels"}
    if points is not None:
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
    return out


def floor_surface(cam: Camera, depth: np.ndarray, boxes: list[ScanBox]) -> tuple[SupportSurface | None, str]:
    """A floor slab from a horizontal plane in the depth points, else from the lowest box bottom."""
    pts = cam.depth_to_points(depth, stride=4)
    z = None
    how = "none"
    if len(pts) >= 200:
        fit = fit_floor(pts, np.array([0.0, 0.0, 1.0]), np.random.default_rng(0), max_tilt_deg=10.0, iterations=150)
        if fit is not None and fit[0][2] > np.cos(np.deg2rad(10.0)):
            z, how = float(fit[1][2]), "depth_plane"
    if boxes:
        lowest = min(b.box.bottom_z for b in boxes)
        if z is None or lowest < z - 0.15:  # the plane found is a table top, not the floor
            z, how = lowest, "lowest_box"
    if z is None:
        return None, how
    c = cam.position
    slab = Box3D(np.array([c[0], c[1], z - 0.01]), np.array([30.0, 30.0, 0.02]), np.eye(3))
    return SupportSurface("floor", "floor", slab, None, "the floor"), how


def object_surfaces(objects: list[ObjectInstance]) -> list[SupportSurface]:
    """Top faces of furniture that things stand on (tables, desks, counters, shelves, night stands...)."""
    out = []
    for o in objects:
        kind = SUPPORT_KINDS.get(o.category)
        if kind is None:
            continue
        b = o.box
        top = b.top_z
        slab = Box3D(np.array([b.center[0], b.center[1], top - 0.01]), np.array([b.size[0], b.size[1], 0.02]), b.rotation)
        out.append(SupportSurface(f"obj{o.id}", kind, slab, o.id, f"the {o.category}"))
    return out


def instance_map(view: ScanView, owner: np.ndarray | None) -> np.ndarray | None:
    """(H, W) instance id of the point each pixel shows (-1: no point), when the view has labels."""
    if owner is None or view.point_labels is None or not view.box_instance:
        return None
    lab = np.asarray(view.point_labels, np.int64)
    return np.where(owner >= 0, lab[np.clip(owner, 0, len(lab) - 1)], -1)


def _withhold_unexplained(view: ScanView, cam: Camera, depth: np.ndarray, floor_z: float,
                          config: dict[str, Any]) -> int:
    """Unknown depth on the floor under unannotated things standing on it (occupancy.py), in place."""
    from refspatial_gen.sources.scan.occupancy import floor_footprints, unexplained_points, withhold_floor

    labels = view.point_labels if bool(cfg(config, "instance_labels")) else None
    structural = set(view.meta.get("structural_instances", []))
    un = unexplained_points(view.points, view.boxes, floor_z, labels, view.box_instance, structural)
    fps = floor_footprints(view.points, un, floor_z, point_spacing(view.points), int(cfg(config, "unexplained_min_points")))
    return withhold_floor(depth, cam, fps, floor_z)


def view_to_frame(view: ScanView, config: dict[str, Any]) -> Frame:
    """Check one view and turn it into a Frame with visible objects; raise DropUnit with a reason otherwise."""
    cam = view.camera
    check_pose(cam)
    rgb = view.rgb
    if rgb is None or rgb.ndim != 3 or rgb.shape[2] != 3 or rgb.dtype != np.uint8:
        raise DropUnit("image_unreadable", f"rgb is not HxWx3 uint8: {None if rgb is None else (rgb.shape, rgb.dtype)}")
    if rgb.shape[:2] != (cam.height, cam.width):
        raise DropUnit("image_size_mismatch", f"image {rgb.shape[:2]} vs intrinsics {(cam.height, cam.width)}")
    depth = view.depth
    if depth is not None:
        check_depth(depth, rgb.shape[:2])
    w0 = cam.width
    rgb, depth, cam = resize_view(rgb, depth, cam, int(cfg(config, "max_width")))
    if cam.width != w0:  # annotated 2D boxes follow the image into the emitted pixel grid
        sx, sy = cam.width / w0, cam.height / view.rgb.shape[0]
        for sb in view.boxes:
            b = sb.provenance.get("bbox2d_annotated")
            if b is not None:
                sb.provenance["bbox2d_annotated"] = [round(b[0] * sx, 3), round(b[1] * sy, 3), round(b[2] * sx, 3), round(b[3] * sy, 3)]
    meta: dict[str, Any] = {"reader": view.reader, "view_id": view.view_id, "gravity_source": view.gravity_source,
                            **view.meta}
    owner = None  # per pixel, the index of the point it shows (point clouds only)
    if depth is None:
        if view.points is None or len(view.points) == 0:
            raise DropUnit("depth_missing", "no depth map and no point cloud to derive one from")
        spacing = point_spacing(view.points)
        depth, owner = splat_depth(view.points, cam, spacing, float(cfg(config, "splat_scale")), with_owner=True)
        meta["depth_source"] = "splatted_points"
        meta["point_spacing_m"] = round(spacing, 4)
        check_depth(depth, rgb.shape[:2])
    else:
        meta.setdefault("depth_source", "sensor")
    depth = depth.astype(np.float32)
    score = blur_score(rgb)
    meta["blur_score"] = round(score, 3)
    if score < float(cfg(config, "blur_threshold")):
        raise DropUnit("blurry", f"variance of Laplacian {score:.1f} < {cfg(config, 'blur_threshold')}")
    objects: list[ObjectInstance] = []
    excluded: list[dict[str, Any]] = []
    visible: list[tuple[ScanBox, dict[str, Any]]] = []
    for sb in sorted(view.boxes, key=lambda b: b.id):
        pc = cam.world_to_cam(sb.box.corners())
        if np.all(pc[:, 2] <= 0):
            if view.boxes_per_frame:
                raise DropUnit("box_behind_camera", f"annotated box {sb.id} ({sb.category}) lies behind the camera")
            continue
        vis = object_visibility(cam, depth, sb.box, config, cam.gravity_known, view.points,
                                float(meta.get("point_spacing_m", 0.0)) * float(cfg(config, "splat_scale")))
        if vis is not None:
            visible.append((sb, vis))
    # a pixel whose depth point lies in several boxes (a mug resting in the padded top of a table box)
    # belongs to the smallest of them: masks are exclusive, like a segmentation
    box_owner = np.zeros((cam.height, cam.width), np.int64)
    for sb, vis in sorted(visible, key=lambda x: (-x[0].box.volume, x[0].id)):
        box_owner[vis["claim"]] = sb.id
    label_map = instance_map(view, owner) if bool(cfg(config, "instance_labels")) else None
    truth: dict[str, int] = {}
    for sb, vis in visible:
        m = vis["mask"] & (box_owner == sb.id)
        trimmed = 0
        inst = view.box_instance.get(sb.id) if label_map is not None else None
        if inst is not None:  # labelled points: only the pixels showing this box's own instance
            other = m & (label_map >= 0) & (label_map != inst)
            trimmed = int(other.sum())
            m &= ~other
        area = int(m.sum())
        cat = category_phrase(sb.category)
        if area < int(cfg(config, "min_mask_pixels")) or vis["visible_fraction"] < float(cfg(config, "min_visible_fraction")):
            if area > 0:
                excluded.append({"id": sb.id, "category": cat, "visible_pixels": area,
                                 "visible_fraction": round(float(vis["visible_fraction"]), 4)})
            if trimmed and area < int(cfg(config, "min_mask_pixels")):
                truth["mask_of_other_instances"] = truth.get("mask_of_other_instances", 0) + 1
            continue
        ys, xs = np.nonzero(m)
        prov = {"source": "scan", "reader": view.reader, "annotation_id": sb.id, "raw_category": sb.category,
                "visible_pixels": area, "pixels_given_to_smaller_boxes": int(vis["visible_pixels"]) - area, "occluded_pixels": vis["occluded_pixels"],
                "see_through_pixels": vis["see_through_pixels"], "fraction_method": vis["fraction_method"],
                **({"pixels_of_other_instances": trimmed, "instance": int(inst)} if inst is not None else {}),
                **sb.provenance}
        objects.append(ObjectInstance(
            id=int(sb.id), category=cat, box=sb.box, mask=RLE.encode(m),
            bbox2d=(float(xs.min()), float(ys.min()), float(xs.max() + 1), float(ys.max() + 1)),
            visible_fraction=float(min(1.0, vis["visible_fraction"])), name=sb.name, attributes=dict(sb.attributes),
            front=sb.front, front_phrase=sb.front_phrase, provenance=prov))
    meta["excluded_objects"] = excluded
    if len(objects) < int(cfg(config, "min_visible_objects")):
        raise DropUnit("too_few_visible_objects", f"{len(objects)} visible < {cfg(config, 'min_visible_objects')}")
    surfaces: list[SupportSurface] = []
    if cam.gravity_known:
        floor, how = floor_surface(cam, depth, view.boxes)
        meta["floor_source"] = how
        if floor is not None:
            surfaces.append(floor)
            if view.points is not None and bool(cfg(config, "withhold_unexplained_floor")):
                meta["unexplained_floor_pixels"] = _withhold_unexplained(view, cam, depth, floor.box.top_z, config)
        surfaces.extend(object_surfaces(objects))
    if truth:
        meta["truth"] = truth
    frame_id = f"scan/{view.reader}/{view.scene_id}/{view.view_id}"
    frame = Frame(frame_id, np.ascontiguousarray(rgb), depth, cam, objects, surfaces, source="scan",
                  scene_id=f"{view.reader}/{view.scene_id}", meta=meta)
    try:
        frame.validate()
    except ValueError as e:
        raise DropUnit("frame_invalid", str(e)) from e
    return frame
