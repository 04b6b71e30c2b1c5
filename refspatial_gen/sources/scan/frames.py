"""ScanView -> Frame: frame checks, keyframe tests, object masks (visibility.py has the visibility rule)
and support surfaces."""

from __future__ import annotations

from typing import Any

import numpy as np

from refspatial_gen.core.camera import Camera
from refspatial_gen.core.errors import DropUnit
from refspatial_gen.core.geometry import Box3D
from refspatial_gen.core.mask import RLE
from refspatial_gen.core.model import Frame, ObjectInstance, SupportSurface
from refspatial_gen.sources.scan.checks import blur_score, check_depth, check_pose
from refspatial_gen.sources.scan.gravity import fit_floor
from refspatial_gen.sources.scan.splat import point_spacing, splat_depth
from refspatial_gen.sources.scan.surface import REASON as RECESSED
from refspatial_gen.sources.scan.surface import withhold_recessed
from refspatial_gen.sources.scan.view import ScanBox, ScanView
from refspatial_gen.sources.scan.visibility import object_visibility
from refspatial_gen.truth.labels import UNRELIABLE, unreliable_label

DEFAULTS: dict[str, Any] = {
    "occlusion_tolerance": 0.025,
    "mask_pad": 0.01,
    "floor_margin": 0.03,
    "min_mask_pixels": 16,
    "min_visible_fraction": 0.0,
    "min_visible_objects": 1,
    "blur_threshold": 0.0,
    "max_width": 0,
    "splat_scale": 1.0,
    "instance_labels": True,
    "withhold_unexplained_floor": True,
    "unexplained_min_points": 20,
    "unlabelled_stand_ins": True,
    "max_point_recess": 0.30,
}

SUPPORT_KINDS = {
    "table": "table",
    "desk": "table",
    "coffee table": "table",
    "dining table": "table",
    "side table": "table",
    "counter": "counter",
    "bookshelf": "shelf",
    "shelf": "shelf",
    "night stand": "object",
    "dresser": "object",
    "cabinet": "object",
    "bed": "object",
    "ottoman": "object",
}
CATEGORY_NAMES = {
    "garbagebin": "garbage bin",
    "showercurtrain": "shower curtain",
    "night_stand": "night stand",
    "refridgerator": "refrigerator",
}


def category_phrase(raw: str) -> str:
    """Annotation class name -> the words used in text ("night_stand" -> "night stand")."""
    c = raw.strip().lower()
    return CATEGORY_NAMES.get(c, c.replace("_", " "))


def cfg(config: dict[str, Any], key: str) -> Any:
    v = config.get(key)
    return DEFAULTS[key] if v is None else v


def resize_view(
    rgb: np.ndarray, depth: np.ndarray | None, cam: Camera, max_width: int
) -> tuple[np.ndarray, np.ndarray | None, Camera]:
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
        slab = Box3D(
            np.array([b.center[0], b.center[1], top - 0.01]), np.array([b.size[0], b.size[1], 0.02]), b.rotation
        )
        out.append(SupportSurface(f"obj{o.id}", kind, slab, o.id, f"the {o.category}"))
    return out


def instance_map(view: ScanView, owner: np.ndarray | None) -> np.ndarray | None:
    """(H, W) instance id of the point each pixel shows (-1: no point), when the view has labels."""
    if owner is None or view.point_labels is None or not view.box_instance:
        return None
    lab = np.asarray(view.point_labels, np.int64)
    return np.where(owner >= 0, lab[np.clip(owner, 0, len(lab) - 1)], -1)


def _withhold_unexplained(
    view: ScanView, cam: Camera, depth: np.ndarray, floor_z: float, config: dict[str, Any]
) -> int:
    """Unknown depth on the floor under unannotated things standing on it (occupancy.py), in place."""
    from refspatial_gen.sources.scan.occupancy import floor_footprints, unexplained_points, withhold_floor

    labels = view.point_labels if bool(cfg(config, "instance_labels")) else None
    structural = set(view.meta.get("structural_instances", []))
    un = unexplained_points(view.points, view.boxes, floor_z, labels, view.box_instance, structural)
    fps = floor_footprints(
        view.points, un, floor_z, point_spacing(view.points), int(cfg(config, "unexplained_min_points"))
    )
    return withhold_floor(depth, cam, fps, floor_z)


def _stand_ins(
    view: ScanView,
    cam: Camera,
    depth: np.ndarray,
    owner: np.ndarray | None,
    objects: list[ObjectInstance],
    floor_z: float | None,
    config: dict[str, Any],
) -> tuple[list[ObjectInstance], dict[str, int]]:
    """The objects plus faint stand-ins for what the depth shows and no annotation explains and for what an
    unreliable label's mask may show (unlabelled.py); blobs only with a known floor and when configured."""
    from refspatial_gen.sources.scan.unlabelled import add_stand_ins, explained_pixels

    label_map = instance_map(view, owner) if bool(cfg(config, "instance_labels")) else None
    known = set(view.box_instance.values()) | set(view.meta.get("structural_instances", []))
    boxes = [b.box for b in view.boxes]
    use_floor = floor_z if bool(cfg(config, "unlabelled_stand_ins")) else None
    return add_stand_ins(objects, cam, depth, boxes, use_floor, config, explained_pixels(label_map, known))


def view_to_frame(view: ScanView, config: dict[str, Any]) -> Frame:
    """Check one view and turn it into a Frame with visible objects; raise DropUnit with a reason otherwise."""
    rgb, depth, cam, owner, meta = _checked_view(view, config)
    visible = _visible_boxes(view, cam, depth, config, float(meta.get("point_spacing_m", 0.0)))
    objects, excluded, truth = _objects(view, visible, cam, owner, config)
    meta["excluded_objects"] = excluded
    if len(objects) < int(cfg(config, "min_visible_objects")):
        raise DropUnit("too_few_visible_objects", f"{len(objects)} visible < {cfg(config, 'min_visible_objects')}")
    floor = None
    if cam.gravity_known:
        floor, meta["floor_source"] = floor_surface(cam, depth, view.boxes)
    floor_z = None if floor is None else floor.box.top_z
    objects, counts = _stand_ins(view, cam, depth, owner, objects, floor_z, config)
    truth.update(counts)
    meta["max_point_recess"] = float(cfg(config, "max_point_recess"))
    recessed = withhold_recessed(objects, cam, depth, meta["max_point_recess"])
    if recessed:
        truth[RECESSED] = recessed
    surfaces: list[SupportSurface] = []
    if floor_z is not None:
        surfaces.append(floor)
        if view.points is not None and bool(cfg(config, "withhold_unexplained_floor")):
            meta["unexplained_floor_pixels"] = _withhold_unexplained(view, cam, depth, floor_z, config)
    if cam.gravity_known:
        surfaces.extend(object_surfaces([o for o in objects if not o.provenance.get("distractor_only")]))
    if truth:
        meta["truth"] = truth
    frame_id = f"scan/{view.reader}/{view.scene_id}/{view.view_id}"
    frame = Frame(
        frame_id,
        np.ascontiguousarray(rgb),
        depth,
        cam,
        objects,
        surfaces,
        source="scan",
        scene_id=f"{view.reader}/{view.scene_id}",
        meta=meta,
    )
    try:
        frame.validate()
    except ValueError as e:
        raise DropUnit("frame_invalid", str(e)) from e
    return frame


def _checked_view(
    view: ScanView, config: dict[str, Any]
) -> tuple[np.ndarray, np.ndarray, Camera, np.ndarray | None, dict[str, Any]]:
    """The view's checked (and resized) image, depth (splatted from the points when the view has none) and
    camera, the point each pixel shows (splatted depth only) and the frame's first meta entries."""
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
                sb.provenance["bbox2d_annotated"] = [
                    round(b[0] * sx, 3),
                    round(b[1] * sy, 3),
                    round(b[2] * sx, 3),
                    round(b[3] * sy, 3),
                ]
    meta: dict[str, Any] = {
        "reader": view.reader,
        "view_id": view.view_id,
        "gravity_source": view.gravity_source,
        **view.meta,
    }
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
    return rgb, depth, cam, owner, meta


def _visible_boxes(
    view: ScanView, cam: Camera, depth: np.ndarray, config: dict[str, Any], point_spacing_m: float
) -> list[tuple[ScanBox, dict[str, Any]]]:
    """Each box whose projection meets the image, with its visibility (visibility.py), by box id."""
    visible: list[tuple[ScanBox, dict[str, Any]]] = []
    for sb in sorted(view.boxes, key=lambda b: b.id):
        pc = cam.world_to_cam(sb.box.corners())
        if np.all(pc[:, 2] <= 0):
            if view.boxes_per_frame:
                raise DropUnit("box_behind_camera", f"annotated box {sb.id} ({sb.category}) lies behind the camera")
            continue
        vis = object_visibility(
            cam,
            depth,
            sb.box,
            float(cfg(config, "occlusion_tolerance")),
            float(cfg(config, "mask_pad")),
            float(cfg(config, "floor_margin")),
            cam.gravity_known,
            view.points,
            point_spacing_m * float(cfg(config, "splat_scale")),
        )
        if vis is not None:
            visible.append((sb, vis))
    return visible


def _objects(
    view: ScanView,
    visible: list[tuple[ScanBox, dict[str, Any]]],
    cam: Camera,
    owner: np.ndarray | None,
    config: dict[str, Any],
) -> tuple[list[ObjectInstance], list[dict[str, Any]], dict[str, int]]:
    """The objects with exclusive masks, the boxes seen too little (excluded) and the truth counts."""
    # a pixel whose depth point lies in several boxes (a mug resting in the padded top of a table box)
    # belongs to the smallest of them: masks are exclusive, like a segmentation
    box_owner = np.zeros((cam.height, cam.width), np.int64)
    for sb, vis in sorted(visible, key=lambda x: (-x[0].box.volume, x[0].id)):
        box_owner[vis["claim"]] = sb.id
    label_map = instance_map(view, owner) if bool(cfg(config, "instance_labels")) else None
    objects: list[ObjectInstance] = []
    excluded: list[dict[str, Any]] = []
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
        if area < int(cfg(config, "min_mask_pixels")) or vis["visible_fraction"] < float(
            cfg(config, "min_visible_fraction")
        ):
            if area > 0:
                excluded.append(
                    {
                        "id": sb.id,
                        "category": cat,
                        "visible_pixels": area,
                        "visible_fraction": round(float(vis["visible_fraction"]), 4),
                    }
                )
            if trimmed and area < int(cfg(config, "min_mask_pixels")):
                truth["mask_of_other_instances"] = truth.get("mask_of_other_instances", 0) + 1
            continue
        ys, xs = np.nonzero(m)
        vis_fraction = float(min(1.0, vis["visible_fraction"]))
        why = unreliable_label(cat)
        if why is not None:  # a distractor only: the visibility floor takes its phrase and answer point
            truth[UNRELIABLE] = truth.get(UNRELIABLE, 0) + 1
        prov = {
            "source": "scan",
            "reader": view.reader,
            "annotation_id": sb.id,
            "raw_category": sb.category,
            "visible_pixels": area,
            "pixels_given_to_smaller_boxes": int(vis["visible_pixels"]) - area,
            "occluded_pixels": vis["occluded_pixels"],
            "see_through_pixels": vis["see_through_pixels"],
            "fraction_method": vis["fraction_method"],
            **({"pixels_of_other_instances": trimmed, "instance": int(inst)} if inst is not None else {}),
            **sb.provenance,
            **(why.provenance(vis_fraction) if why else {}),
        }
        objects.append(
            ObjectInstance(
                id=int(sb.id),
                category=cat,
                box=sb.box,
                mask=RLE.encode(m),
                bbox2d=(float(xs.min()), float(ys.min()), float(xs.max() + 1), float(ys.max() + 1)),
                visible_fraction=0.0 if why else vis_fraction,
                name=sb.name,
                attributes=dict(sb.attributes),
                front=sb.front,
                front_phrase=sb.front_phrase,
                provenance=prov,
            )
        )
    return objects, excluded, truth
