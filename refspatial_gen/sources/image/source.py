"""The `image` source: annotated photos + depth (estimated or provided) + intrinsics -> lifted 3D Frames.

Unit key: "image:<image id>": no folder, so moving or copying the collection changes neither the keys nor
(the unit's random generator derives from the key) the output bytes. `load` reads the collection from
`config["_input"]`, the absolute input folder the recipe loader puts in every source's config.
One unit = one photo = one Frame. Whole-image problems raise DropUnit with a reason (`image_undecodable`,
`image_size_mismatch`, `annotation_out_of_bounds`, `annotation_size_mismatch`, `depth_size_mismatch`, `depth_missing`, `depth_not_metric`, `too_few_objects`, ...); single objects are
dropped with a reason counted in `Frame.meta["dropped_objects"]`.
"""

from __future__ import annotations

import time
from dataclasses import replace
from functools import lru_cache
from pathlib import Path
from typing import Any

import numpy as np

from refspatial_gen.core.camera import Camera
from refspatial_gen.core.errors import DropUnit
from refspatial_gen.core.geometry import Box3D, rot_z
from refspatial_gen.core.mask import RLE
from refspatial_gen.core.model import Frame, ObjectInstance, SupportSurface
from refspatial_gen.perception.config import perception_field
from refspatial_gen.schema import Field
from refspatial_gen.sources.image import filters as F
from refspatial_gen.sources.image.annotations import (
    FORMATS, GROUND_STUFF_PREFIXES, SUPPORT_STUFF_PREFIXES, Collection, ImageRecord, annotation_mask,
    load_collection, read_panoptic_ids,
)
from refspatial_gen.sources.image.checks import raise_if_invalid
from refspatial_gen.sources.image.intrinsics import MODES, Intrinsics, resolve_intrinsics

KEY_PREFIX = "image:"
# thing categories whose top is a support surface when a horizontal plane lies on them
SUPPORT_CATEGORIES = ("dining table", "table", "desk", "bed", "counter", "bench", "night_stand", "dresser",
                      "coffee_table", "sofa", "couch", "shelf", "cabinet")


def _depth_check(v: Any) -> str | None:
    from refspatial_gen.depth import check_options

    if not isinstance(v, dict):
        return "must be a mapping with an 'estimator' key"
    name = v.get("estimator")
    if not isinstance(name, str):
        return "needs 'estimator' (one of depth-anything, geometric, onnx, provided)"
    return check_options(name, {k: x for k, x in v.items() if k != "estimator"})


def _pair_check(v: Any) -> str | None:
    if not (isinstance(v, list) and len(v) == 2 and all(isinstance(x, (int, float)) for x in v) and v[0] < v[1]):
        return "must be [lo, hi] with lo < hi"
    return None


CONFIG_FIELDS: dict[str, Field] = {
    "format": Field(str, default="auto", choices=FORMATS, doc="annotation format of the input folder"),
    "annotations": Field(str, default=None, doc="annotation file inside the input folder (default: detected)"),
    "images_dir": Field(str, default=None, doc="image folder inside the input folder (default: detected)"),
    "depth": Field(dict, default={"estimator": "geometric"}, check=_depth_check,
                   doc="depth estimator: {estimator: NAME, ...its options}"),
    "intrinsics": Field(str, default="auto", choices=MODES, doc="provided | exif | fov prior | auto (in that order)"),
    "hfov_deg": Field(float, default=60.0, min=5.0, max=170.0, doc="horizontal field of view prior"),
    "gravity": Field(str, default="auto", choices=("auto", "plane", "prior", "none"),
                     doc="auto: the depth prior for geometric depth, else a RANSAC floor/table plane"),
    "camera_height": Field(float, default=1.5, min=0.05, doc="camera height prior (m)"),
    "camera_pitch_deg": Field(float, default=0.0, min=-60.0, max=80.0, doc="downward pitch prior (deg)"),
    "max_tilt_deg": Field(float, default=40.0, min=1.0, max=89.0, doc="largest tilt of a plane taken as horizontal"),
    "categories": Field(list, default=None, doc="only these categories become objects (default: all things)"),
    "min_mask_area": Field(int, default=200, min=1, doc="smallest visible mask (pixels)"),
    "min_mask_fraction": Field(float, default=0.0005, min=0.0, max=1.0, doc="smallest mask as a fraction of the image"),
    "min_valid_depth_fraction": Field(float, default=0.3, min=0.0, max=1.0),
    "min_points": Field(int, default=30, min=3),
    "max_points_per_object": Field(int, default=1500, min=50),
    "min_instance_spread": Field(float, default=0.1, min=0.0, doc="median nearest-neighbour centre distance (m)"),
    "max_instances_per_category": Field(int, default=12, min=1),
    "complete_categories": Field(bool, default=True, doc="drop a whole category when one instance is dropped"),
    "complete_depth": Field(bool, default=True, doc="grow boxes along the view direction (amodal prior)"),
    "snap_to_support": Field(bool, default=True),
    "keep_truncated_contacts": Field(bool, default=False,
                                     doc="geometric depth: keep objects cut by the bottom edge (contact unseen)"),
    "min_objects": Field(int, default=2, min=1),
    "max_objects": Field(int, default=40, min=1),
    # truth checks (docs/quality.md): the photo's camera fitted to its objects, sizes against their ranges
    "fit_camera": Field(bool, default=True, doc="geometric depth: fit camera height and pitch per photo to the "
                                               "ground-standing objects of known size (the camera above is the prior)"),
    "fit_pitch_range_deg": Field(list, default=[-15.0, 45.0], check=_pair_check, doc="pitch search range (deg)"),
    "fit_height_range": Field(list, default=[0.3, 30.0], check=_pair_check, doc="camera height search range (m)"),
    "fit_min_inlier_share": Field(float, default=0.6, min=0.0, max=1.0,
                                  doc="share of those objects that must fit their range for a reliable metric scale"),
    "fit_min_anchors": Field(int, default=2, min=1, doc="agreeing objects needed before the metric scale counts "
                                                         "as verified (one object fits any camera)"),
    "size_check": Field(bool, default=True, doc="remove objects whose lifted box is outside their category's range"),
    "size_tolerance": Field(float, default=0.0, min=0.0, max=1.0, doc="ranges are widened by this fraction"),
    "max_box_overlap": Field(float, default=0.25, min=0.0, max=1.0,
                             doc="geometric depth: two boxes sharing more of the smaller one's volume pass through "
                                 "each other; the occluded one is removed (1 = off)"),
    "perception": perception_field(),  # unlabelled photos: annotations from local models (docs/perception.md)
}


def unit_key(image_id: str) -> str:
    """`image:<image id>` (the id as the annotations give it; no folder, see the module docstring)."""
    return f"{KEY_PREFIX}{image_id}"


def parse_key(key: str) -> str:
    """`image:<image id>` -> image id."""
    if not key.startswith(KEY_PREFIX) or len(key) == len(KEY_PREFIX):
        raise DropUnit("bad_unit_key", key)
    return key[len(KEY_PREFIX):]


def input_root(config: dict[str, Any]) -> Path:
    """The collection folder unit keys resolve against (`_input`, set by the recipe loader from --input/`input:`)."""
    base = (config or {}).get("_input")
    if not base:
        raise ValueError("image load() needs config['_input'] (the input folder; the recipe loader sets it "
                         "from --input or the recipe's `input:`)")
    return Path(base).resolve()


@lru_cache(maxsize=4)
def _estimator(name: str, options: tuple):
    from refspatial_gen.depth import get_estimator

    return get_estimator(name, dict(options))


def estimator_from_config(cfg: dict[str, Any]):
    d = dict(cfg.get("depth") or {"estimator": "geometric"})
    name = d.pop("estimator")
    return name, _estimator(name, tuple(sorted((k, tuple(v) if isinstance(v, list) else v) for k, v in d.items())))


def decode_rgb(path: Path) -> np.ndarray:
    """Strict decode (a truncated JPEG is an error, not a grey half image)."""
    from PIL import Image

    if not path.is_file():
        raise DropUnit("image_missing", str(path.name))
    try:
        with Image.open(path) as im:
            im.load()
            rgb = np.asarray(im.convert("RGB"), dtype=np.uint8)
    except (OSError, ValueError, SyntaxError) as e:  # PIL raises these for corrupt/truncated files
        raise DropUnit("image_undecodable", f"{path.name}: {e}") from e
    return np.ascontiguousarray(rgb)


def _stuff_kind(name: str) -> str | None:
    n = name.lower()
    if n.startswith(GROUND_STUFF_PREFIXES):
        return "ground"
    if n.startswith(SUPPORT_STUFF_PREFIXES):
        return "support"
    return None


def _surface_box(world_pts: np.ndarray, top_z: float) -> Box3D | None:
    import cv2

    if len(world_pts) < 10:
        return None
    xy = world_pts[:, :2]
    lo, hi = np.percentile(xy, [2, 98], axis=0)
    xy = xy[np.all((xy >= lo) & (xy <= hi), axis=1)]
    if len(xy) < 10:
        return None
    (cx, cy), (w, h), ang = cv2.minAreaRect(xy.astype(np.float32))
    if w <= 0 or h <= 0:
        return None
    return Box3D(np.array([cx, cy, top_z - 0.01]), np.array([w, h, 0.02]), rot_z(np.deg2rad(ang)))


class ImageSource:
    """Annotated 2D photos lifted to 3D. See docs/image.md."""

    name = "image"
    CONFIG_FIELDS = CONFIG_FIELDS

    def unit_keys(self, config: dict[str, Any], scenes: int | None, input_path: str | None) -> list[str]:
        if not input_path:
            raise ValueError("the image source needs an input folder (recipe `input:` or --input)")
        cfg = _with_defaults(config)
        if cfg["perception"]:
            from refspatial_gen.perception.photos import photo_ids
            keys = [unit_key(iid) for iid in photo_ids(input_path, cfg)]
            return keys if scenes is None else keys[:scenes]
        coll = load_collection(input_path, cfg["format"], cfg["annotations"], cfg["images_dir"])
        keys = [unit_key(iid) for iid in coll.ids()]
        return keys if scenes is None else keys[:scenes]

    def load(self, unit_key: str, rng: np.random.Generator, config: dict[str, Any]) -> list[Frame]:
        iid = parse_key(unit_key)
        root = input_root(config)
        cfg = _with_defaults(config)
        if cfg["perception"]:
            from refspatial_gen.perception.photos import load_photo
            return [load_photo(root, iid, rng, cfg, build_frame)]
        coll = load_collection(root, cfg["format"], cfg["annotations"], cfg["images_dir"])
        rec = coll.images.get(iid)
        if rec is None:
            raise DropUnit("unknown_image", f"{iid} not in {root}")
        raise_if_invalid(rec.meta)  # a malformed annotation entry drops its image (sources/image/checks.py)
        return [build_frame(coll, rec, rng, cfg)]


def _with_defaults(config: dict[str, Any] | None) -> dict[str, Any]:
    cfg = {k: f.default for k, f in CONFIG_FIELDS.items()}
    cfg.update({k: v for k, v in (config or {}).items() if v is not None})
    return cfg


def build_frame(coll: Collection, rec: ImageRecord, rng: np.random.Generator, cfg: dict[str, Any],
                timings: dict[str, float] | None = None) -> Frame:
    """One annotated photo -> one Frame (or DropUnit)."""
    from refspatial_gen.depth import CameraPrior
    from refspatial_gen.sources.image.gravity import GravityEstimate, estimate_gravity, world_from_cam
    from refspatial_gen.sources.image import lift as _lift
    from refspatial_gen.sources.image.amodal import fit_to_box2d
    LiftParams, lift_object = _lift.LiftParams, _lift.lift_object

    cfg = _with_defaults(cfg)
    tm = timings if timings is not None else {}
    t0 = time.perf_counter()
    rgb = decode_rgb(rec.file)
    H, W = rgb.shape[:2]
    if (rec.width is not None and rec.width != W) or (rec.height is not None and rec.height != H):
        raise DropUnit("image_size_mismatch", f"{rec.file.name}: decoded {W}x{H}, annotation says {rec.width}x{rec.height}")
    tm["decode"] = time.perf_counter() - t0

    t0 = time.perf_counter()
    intr: Intrinsics = resolve_intrinsics(cfg["intrinsics"], rec.file, W, H, cfg["hfov_deg"], rec.intrinsics)
    pan = read_panoptic_ids(rec.panoptic_png, W, H, rec.image_id) if rec.panoptic_png is not None else None
    cands: list[F.Candidate] = []
    crowd: set[str] = set()
    ground = np.zeros((H, W), bool)
    support_stuff: list[tuple[str, np.ndarray]] = []
    wanted = set(cfg["categories"]) if cfg["categories"] else None
    ignored: dict[str, int] = {}
    for ann in rec.annotations:
        mask, is_seg = annotation_mask(ann, rec, W, H, pan)  # raises DropUnit for out-of-image annotations
        if not ann.isthing:
            kind = _stuff_kind(ann.category)
            if kind == "ground":
                ground |= mask
            elif kind == "support":
                support_stuff.append((ann.category, mask))
            continue
        if ann.iscrowd:
            crowd.add(ann.category)
            continue
        if wanted is not None and ann.category not in wanted:
            ignored[ann.category] = ignored.get(ann.category, 0) + 1
            continue
        bb = ann.bbox if not rec.meta.get("normalised_boxes") else (ann.bbox[0] * W, ann.bbox[1] * H, ann.bbox[2] * W, ann.bbox[3] * H)
        c = F.Candidate(ann.ann_id, ann.category, mask, tuple(float(x) for x in bb), is_seg)
        area = int(mask.sum())
        if area < cfg["min_mask_area"] or area < cfg["min_mask_fraction"] * W * H:
            F.drop(c, "too_small")
        cands.append(c)
    F.resolve_overlaps([c for c in cands if c.segmentation])  # box annotations: claimed while lifting
    for c in cands:
        if c.reason is None and int(c.mask.sum()) < cfg["min_mask_area"]:
            F.drop(c, "too_small")
    if cfg["complete_categories"]:
        F.complete_categories(cands, crowd)
    live = [c for c in cands if c.reason is None]
    if len(live) < cfg["min_objects"]:
        raise DropUnit("too_few_objects", f"{rec.image_id}: {len(live)} usable annotated objects before depth")
    tm["annotations"] = time.perf_counter() - t0

    # ---- depth
    t0 = time.perf_counter()
    est_name, est = estimator_from_config(cfg)
    dopts = cfg.get("depth") or {}
    # the camera prior: the depth section's own camera_height/pitch_deg win over the source-level prior
    cam_h = float(dopts.get("camera_height") or cfg["camera_height"])
    pitch = float(np.deg2rad(dopts["pitch_deg"] if dopts.get("pitch_deg") is not None else cfg["camera_pitch_deg"]))
    truth: dict[str, int] = {}
    metric_scale: dict[str, Any] = {"source": "measured", "status": "consistent", "reliable": True}
    if est_name == "geometric":  # the photo's own camera, fitted to its objects of known size
        from refspatial_gen.sources.image.truthcheck import fit_photo_camera

        # every annotated object may testify, also those too small to become objects (distant people
        # near the horizon are what pins the pitch down)
        fit = fit_photo_camera([c for c in cands if c.reason in (None, "too_small")], H, W, intr.fy, intr.cy,
                               cam_h, pitch, cfg)
        cam_h, pitch = fit.camera_height, fit.pitch
        metric_scale = fit.meta()
    elif est_name != "provided":
        metric_scale = {"source": est_name, "status": "unverified", "reliable": False}
    if not metric_scale["reliable"]:
        key = f"metric_scale_{metric_scale['status']}"
        truth[key] = truth.get(key, 0) + 1
    depth_path = None
    if est_name == "provided":
        depth_path = str(rec.depth_file if rec.depth_file is not None else est.resolve_path(rec.file))
    ids = {id(c): k + 1 for k, c in enumerate(live)}
    prior = CameraPrior(W, H, intr.fx, intr.fy, intr.cx, intr.cy, cam_h, pitch,
                        depth_path=depth_path, depth_scale=rec.meta.get("depth_scale"),
                        masks=[(ids[id(c)], c.mask) for c in live],
                        categories={ids[id(c)]: c.category for c in live}, ground_mask=ground if ground.any() else None)
    res = est.estimate(rgb, prior)
    depth = np.asarray(res.depth_m, np.float32)
    if depth.shape != (H, W):
        raise DropUnit("depth_size_mismatch", f"{rec.image_id}: depth {depth.shape} vs image {(H, W)}")
    if not res.is_metric:
        raise DropUnit("depth_not_metric", f"{rec.image_id}: {res.origin} gives relative depth only")
    depth = np.where(np.isfinite(depth) & (depth > 0), depth, 0.0).astype(np.float32)
    tm["depth"] = time.perf_counter() - t0
    t_lift = time.perf_counter()
    for c in live:
        note = res.meta.get("objects", {}).get(str(ids[id(c)]))
        if note is not None:
            c.provenance["contact"] = note.get("contact")
            kind, _, other = str(note.get("contact")).partition(":")
            if kind in ("support", "behind") and other.isdigit():  # the estimator's id -> the annotation
                o = live[int(other) - 1]
                c.provenance["rests_on" if kind == "support" else "behind"] = {"annotation_id": o.ann_id,
                                                                               "category": o.category}
            if note.get("truncated"):
                c.provenance["contact_truncated"] = True
                if not cfg["keep_truncated_contacts"]:
                    F.drop(c, "contact_not_visible")
            if note.get("contact") == "none":
                F.drop(c, note.get("reason", "no_ground_contact"))

    # ---- gravity and world frame
    grav: GravityEstimate
    mode = cfg["gravity"]
    if mode == "auto":
        mode = "prior" if est_name == "geometric" else "plane"
    prior_up = prior.up_cam()
    if mode == "plane":
        st = max(1, int(round(np.sqrt(H * W / 20000.0))))
        vs, us = np.mgrid[0:H:st, 0:W:st]
        z = depth[::st, ::st]  # (us + 0.5, vs + 0.5): pixel centres in Camera's convention
        ok = z > 0  # object tops (tables, beds) are as good a gravity cue as the floor
        pts = np.stack([(us[ok] + 0.5 - intr.cx) * z[ok] / intr.fx, (vs[ok] + 0.5 - intr.cy) * z[ok] / intr.fy,
                        z[ok]], axis=1)
        g = estimate_gravity(pts, rng, prior_up, cfg["max_tilt_deg"])
        if g is None:
            grav = GravityEstimate(prior_up, False, "unknown", None, detail={"why": "no horizontal plane found"})
        else:
            grav = g
            grav.detail["pixels"] = (us[ok], vs[ok])
    elif mode == "prior":
        grav = GravityEstimate(prior_up, True, "prior", cam_h,
                               detail={"pitch_deg": round(float(np.rad2deg(pitch)), 4), "roll_deg": 0.0})
    else:
        grav = GravityEstimate(prior_up, False, "unknown", None, detail={"why": "gravity: none"})
    T = world_from_cam(grav.up_cam, grav.camera_height)
    cam = Camera(W, H, intr.fx, intr.fy, intr.cx, intr.cy, T, gravity_known=grav.known)
    support_z = [float(cam.position[2] - pl.d) for pl in grav.planes]
    if est_name == "geometric" and grav.known:
        support_z = [0.0]  # the prior's ground plane: ground contacts snap their bottoms to it
    Tcw = cam.cam_from_world
    walls = [(Tcw[:3, :3].T @ w.n, float(w.n @ Tcw[:3, 3] + w.d)) for w in grav.walls]

    # ---- lifting
    params = LiftParams(max_points=cfg["max_points_per_object"], min_points=cfg["min_points"],
                        min_valid_fraction=cfg["min_valid_depth_fraction"], complete_depth=cfg["complete_depth"],
                        snap_distance=0.25 if cfg["snap_to_support"] else 0.0)
    claimed = np.zeros((H, W), bool)  # box annotations: pixels already taken by a smaller box's object
    layered = _box_masks(live, depth, cam, support_z, walls, params) if est_name != "geometric" else {}
    pending: list[F.Candidate] = []  # box annotations lifted, awaiting amodal completion
    for c in sorted(live, key=lambda c: (c.segmentation, int(c.mask.sum()), c.ann_id)):
        if c.reason is not None:
            continue
        bm = layered.get(id(c))
        if bm is not None:
            ys, xs = np.nonzero(bm & ~claimed)
        else:
            ys, xs = np.nonzero(c.mask & ~claimed) if not c.segmentation else np.nonzero(c.mask)
        zz = depth[ys, xs]
        ok = zz > 0
        if ok.sum() < params.min_points or ok.mean() < params.min_valid_fraction:
            F.drop(c, "low_valid_depth")
            continue
        ys, xs, zz = ys[ok], xs[ok], zz[ok]
        weights = None
        if not c.segmentation and bm is None:  # box annotation: the object fills the box centre, clutter its rim
            x0, y0, x1, y1 = c.bbox2d
            cx_, cy_, hw, hh = (x0 + x1) / 2, (y0 + y1) / 2, (x1 - x0) / 4, (y1 - y0) / 4
            weights = np.where((np.abs(xs - cx_) <= hw) & (np.abs(ys - cy_) <= hh), 1.0, 0.2)
        if bm is not None:
            out = lift_object(xs, ys, zz, cam, replace(params, complete_depth=False), support_z, walls,
                              preselected=True)
        else:
            out = lift_object(xs, ys, zz, cam, params, support_z, walls, weights)
        if isinstance(out, str):
            F.drop(c, out)
            continue
        if bm is not None:  # box annotation: fit to its 2D box now, support and depth completion below
            out.box, n_fit = fit_to_box2d(out.box, c.bbox2d, cam)
            out.notes.update(n_fit)
            pending.append(c)
        if str(c.provenance.get("contact", "")).startswith("behind:") and out.box.bottom_z > 0:
            # its foot is hidden behind the occluder: it stands on the ground (amodal completion)
            out.box = _with_bottom(out.box, 0.0)
            out.notes["occluded_completed"] = True
        c.box = out.box
        c.provenance.update({k: v for k, v in out.notes.items()})
        c.provenance["points"] = out.points_used
        if not c.segmentation and est_name != "geometric":
            # a box annotation: the visible mask is the box pixels whose 3D point lies on the object
            allw = cam.cam_to_world(cam.backproject(xs + 0.5, ys + 0.5, zz))
            vis = out.keep_pixels & out.visible_box.contains(allw, pad=0.03)
            m = np.zeros((H, W), bool)
            m[ys[vis], xs[vis]] = True
            if m.sum() < cfg["min_mask_area"]:  # too few box pixels have depth on the object
                F.drop(c, "too_small")
                continue
            c.mask = m
            claimed |= m
            c.provenance["mask"] = "box_refined_by_depth"
        else:
            c.provenance["mask"] = "segmentation" if c.segmentation else "box"
    _complete_box_annotations([c for c in pending if c.reason is None], depth, cam, support_z, params)
    from refspatial_gen.sources.image.truthcheck import check_sizes

    check_sizes(cands, cfg, est_name != "geometric", truth)
    if est_name == "geometric" and cfg["max_box_overlap"] < 1.0:
        from refspatial_gen.sources.image.truthcheck import check_interpenetration

        check_interpenetration(cands, float(cfg["max_box_overlap"]), truth)
    F.instances_not_spread(cands, cfg["min_instance_spread"])
    F.too_many_instances(cands, cfg["max_instances_per_category"])
    if cfg["complete_categories"]:
        F.complete_categories(cands, crowd)
    final = [c for c in cands if c.reason is None]
    if len(final) > cfg["max_objects"]:
        raise DropUnit("too_many_objects", f"{rec.image_id}: {len(final)} objects > max_objects")
    if len(final) < cfg["min_objects"]:
        raise DropUnit("too_few_objects", f"{rec.image_id}: {len(final)} objects after lifting "
                                          f"(dropped: {F.drop_counts(cands)})")

    # ---- frame
    objects: list[ObjectInstance] = []
    for k, c in enumerate(final):
        ys, xs = np.nonzero(c.mask)
        bbox2d = (float(xs.min()), float(ys.min()), float(xs.max() + 1), float(ys.max() + 1))
        prov = {"source": "image", "format": coll.format, "annotation_id": c.ann_id,
                "depth": res.origin, **c.provenance}
        objects.append(ObjectInstance(id=k + 1, category=c.category, box=c.box, mask=RLE.encode(c.mask),
                                      bbox2d=bbox2d, visible_fraction=1.0, provenance=prov))
    surfaces = _surfaces(grav, cam, depth, ground, support_stuff, final, objects, res, est_name)
    tm["lift"] = time.perf_counter() - t_lift
    grav_meta = {"origin": grav.origin, "known": grav.known,
                 "camera_height": None if grav.camera_height is None else round(float(grav.camera_height), 4),
                 **{k: v for k, v in grav.detail.items() if k != "pixels"}}
    meta = {
        "image_id": rec.image_id, "image_file": rec.file.name, "annotation_format": coll.format,
        "intrinsics": intr.meta(), "depth": {"origin": res.origin, "is_metric": res.is_metric,
                                            **{k: v for k, v in res.meta.items() if k != "objects"}},
        "gravity": grav_meta, "dropped_objects": F.drop_counts(cands),
        "dropped_object_list": [{"annotation_id": c.ann_id, "category": c.category, "reason": c.reason}
                                for c in cands if c.reason is not None],
        "crowd_categories": sorted(crowd), "ignored_categories": dict(sorted(ignored.items())),
        "metric_scale": metric_scale, "truth": dict(sorted(truth.items())),
    }
    fid = unit_key(rec.image_id)  # no folder name: a renamed or moved copy gives the same bytes
    return Frame(fid, rgb, depth, cam, objects, surfaces, source="image", scene_id=fid, meta=_jsonable(meta))


def _with_bottom(box: Box3D, bottom: float) -> Box3D:
    c, s = box.center.copy(), box.size.copy()
    top = box.top_z
    c[2], s[2] = (top + bottom) / 2, top - bottom
    return Box3D(c, s, box.rotation)


def _box_masks(live: list[F.Candidate], depth: np.ndarray, cam: Camera, support_z: list[float],
               walls: list[tuple[np.ndarray, float]], params) -> dict[int, np.ndarray]:
    """Box annotations: visible masks by depth layering of the overlapping boxes (boxseg.py), by id(c)."""
    from refspatial_gen.sources.image.boxseg import assign_boxes

    boxes = [c for c in live if c.reason is None and not c.segmentation]
    if not boxes:
        return {}
    H, W = depth.shape
    vs, us = np.mgrid[0:H, 0:W]
    ok = depth > 0
    world = np.zeros((H, W, 3))
    world[ok] = cam.cam_to_world(cam.backproject(us[ok] + 0.5, vs[ok] + 0.5, depth[ok]))
    bm = assign_boxes(depth, world, [c.bbox2d for c in boxes], support_z, walls, band=params.plane_band, cam=cam)
    for c, note in zip(boxes, bm.notes):
        c.provenance["box_layering"] = note
    return {id(c): m for c, m in zip(boxes, bm.masks)}


def _complete_box_annotations(cands: list[F.Candidate], depth: np.ndarray, cam: Camera, support_z: list[float],
                              params) -> None:
    """Amodal completion of lifted box annotations (amodal.py): down to what they stand on (a support
    plane or another object's top) when the added part would be hidden, then along the view direction."""
    from refspatial_gen.sources.image.amodal import complete_to_support, supports_below
    from refspatial_gen.sources.image.lift import complete_along_view

    def deep(b):
        return complete_along_view(b, cam.position[:2])[0] if params.complete_depth else b

    boxes = {id(c): c.box for c in cands}  # after fitting to the 2D box, before any completion
    footprints = {k: deep(b) for k, b in boxes.items()}
    for c in cands:
        others = [(boxes[id(o)], footprints[id(o)]) for o in cands if o is not c]
        sup = supports_below(boxes[id(c)], footprints[id(c)], support_z, others, params.plane_band)
        box, notes = complete_to_support(boxes[id(c)], depth, cam, sup, params.plane_band)
        if params.complete_depth:
            box, grow = complete_along_view(box, cam.position[:2])
            if grow > 0:
                notes["depth_completed"] = round(grow, 4)
        c.box = box
        c.provenance.update(notes)


def _surfaces(grav, cam: Camera, depth: np.ndarray, ground: np.ndarray, support_stuff, final, objects, res,
              est_name: str) -> list[SupportSurface]:
    """Named horizontal support surfaces only: a plane is named by the object or stuff it lies on (a
    single instance of a support category, or panoptic table/floor stuff) or, when it is the lowest plane
    at least 0.9 m under the camera, 'the floor'. Unnamed planes only serve gravity."""
    out: list[SupportSurface] = []
    H, W = depth.shape
    if est_name == "geometric" or not grav.planes:
        if ground.any() and grav.known and est_name == "geometric":
            ys, xs = np.nonzero(ground & (depth > 0))
            if len(ys) > 50:
                step = max(1, len(ys) // 4000)
                pts = cam.cam_to_world(cam.backproject(xs[::step] + 0.5, ys[::step] + 0.5, depth[ys[::step], xs[::step]]))
                b = _surface_box(pts, 0.0)
                if b is not None:
                    out.append(SupportSurface("ground", "floor", b, None, "the ground"))
        return out
    us, vs = grav.detail.get("pixels", (None, None))
    if us is None:
        return out
    cats = [c.category for c in final]
    lowest = min(range(len(grav.planes)), key=lambda i: grav.planes[i].d * -1)
    for i, pl in enumerate(grav.planes):
        pu, pv = us[pl.inliers], vs[pl.inliers]
        top = float(cam.position[2] - pl.d)
        name, kind, oid = None, None, None
        for o, c in zip(objects, final):
            if c.category in SUPPORT_CATEGORIES and cats.count(c.category) == 1:
                m = o.mask.decode()
                if m[pv, pu].mean() > 0.5:
                    name, kind, oid = f"the {c.category.replace('_', ' ')}", "object", o.id
                    break
        if name is None:
            for sname, m in support_stuff:
                if m[pv, pu].mean() > 0.5:
                    name, kind = f"the {sname.split('-')[0]}", "table"
                    break
        if name is None and i == lowest and pl.d >= 0.9:
            name, kind = "the floor", "floor"
        if name is None:
            continue
        zz = depth[pv, pu]
        pts = cam.cam_to_world(cam.backproject(pu + 0.5, pv + 0.5, zz))
        b = _surface_box(pts, top)
        if b is not None:
            out.append(SupportSurface(f"plane{i}", kind, b, oid, name))
    return out


def _jsonable(x: Any) -> Any:
    if isinstance(x, dict):
        return {str(k): _jsonable(v) for k, v in x.items()}
    if isinstance(x, (list, tuple)):
        return [_jsonable(v) for v in x]
    if isinstance(x, (np.floating, float)):
        return round(float(x), 6)
    if isinstance(x, (np.integer,)):
        return int(x)
    if isinstance(x, np.bool_):
        return bool(x)
    return x
