"""One annotated photo -> one lifted 3D Frame: decode, annotations to candidates, depth (and the photo's
camera fitted to its objects), gravity and the world frame, lifting, truth checks, the Frame.

Whole-image problems raise DropUnit with a reason (`image_undecodable`, `image_size_mismatch`,
`annotation_out_of_bounds`, `annotation_size_mismatch`, `depth_size_mismatch`, `depth_missing`,
`depth_not_metric`, `too_few_objects`, `image_composite`, ...); single objects are dropped with a reason counted in
`Frame.meta["dropped_objects"]`.
"""

from __future__ import annotations

import time
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from refspatial_gen.core.camera import Camera
from refspatial_gen.core.errors import DropUnit
from refspatial_gen.core.mask import RLE
from refspatial_gen.core.model import Frame, ObjectInstance
from refspatial_gen.sources.image import filters as F
from refspatial_gen.sources.image.annotations import Collection, ImageRecord, annotation_mask, read_panoptic_ids
from refspatial_gen.sources.image.composite import raise_if_composite
from refspatial_gen.sources.image.config import estimator_from_config, with_defaults
from refspatial_gen.sources.image.intrinsics import Intrinsics, resolve_intrinsics
from refspatial_gen.sources.image.keys import unit_key
from refspatial_gen.sources.image.lifting import lift_candidates
from refspatial_gen.sources.image.surfaces import stuff_kind, support_surfaces


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


@dataclass
class _Annotated:
    """A photo's annotations sorted out: object candidates, crowd categories, ground and support stuff."""

    cands: list[F.Candidate] = field(default_factory=list)
    crowd: set[str] = field(default_factory=set)
    ground: np.ndarray | None = None
    support_stuff: list[tuple[str, np.ndarray]] = field(default_factory=list)
    ignored: dict[str, int] = field(default_factory=dict)
    live: list[F.Candidate] = field(default_factory=list)


def build_frame(
    coll: Collection,
    rec: ImageRecord,
    rng: np.random.Generator,
    cfg: dict[str, Any],
    timings: dict[str, float] | None = None,
) -> Frame:
    """One annotated photo -> one Frame (or DropUnit)."""
    cfg = with_defaults(cfg)
    tm = timings if timings is not None else {}
    t0 = time.perf_counter()
    rgb = decode_rgb(rec.file)
    H, W = rgb.shape[:2]
    if (rec.width is not None and rec.width != W) or (rec.height is not None and rec.height != H):
        raise DropUnit(
            "image_size_mismatch", f"{rec.file.name}: decoded {W}x{H}, annotation says {rec.width}x{rec.height}"
        )
    raise_if_composite(rgb, float(cfg["composite_max_std"]), rec.file.name)  # a collage: DropUnit image_composite
    tm["decode"] = time.perf_counter() - t0

    t0 = time.perf_counter()
    intr: Intrinsics = resolve_intrinsics(cfg["intrinsics"], rec.file, W, H, cfg["hfov_deg"], rec.intrinsics)
    ann = _annotated(rec, W, H, cfg)
    tm["annotations"] = time.perf_counter() - t0

    t0 = time.perf_counter()
    est_name, est = estimator_from_config(cfg)
    truth: dict[str, int] = {}
    prior, cam_h, pitch, metric_scale, ids = _camera_prior(rec, intr, ann, cfg, est_name, est, truth, H, W)
    res = est.estimate(rgb, prior)
    depth = np.asarray(res.depth_m, np.float32)
    if depth.shape != (H, W):
        raise DropUnit("depth_size_mismatch", f"{rec.image_id}: depth {depth.shape} vs image {(H, W)}")
    if not res.is_metric:
        raise DropUnit("depth_not_metric", f"{rec.image_id}: {res.origin} gives relative depth only")
    depth = np.where(np.isfinite(depth) & (depth > 0), depth, 0.0).astype(np.float32)
    tm["depth"] = time.perf_counter() - t0
    t_lift = time.perf_counter()
    _contact_notes(ann.live, ids, res, cfg)
    grav, cam = _world_frame(depth, intr, prior, cam_h, pitch, est_name, cfg, rng)
    support_z = [float(cam.position[2] - pl.d) for pl in grav.planes]
    if est_name == "geometric" and grav.known:
        support_z = [0.0]  # the prior's ground plane: ground contacts snap their bottoms to it
    Tcw = cam.cam_from_world
    walls = [(Tcw[:3, :3].T @ w.n, float(w.n @ Tcw[:3, 3] + w.d)) for w in grav.walls]
    lift_candidates(ann.live, depth, cam, support_z, walls, cfg, est_name)
    final = _checked_objects(rec, ann, cfg, est_name, truth)
    objects = _objects(final, coll, res)
    if est_name == "geometric":  # positions from the foot: flag objects whose foot is not seen
        from refspatial_gen.sources.image.contact import mark_unseen

        truth.update(mark_unseen(objects, H, float(cfg["foot_border_margin"])))
    surfaces = support_surfaces(grav, cam, depth, ann.ground, ann.support_stuff, final, objects, res, est_name)
    tm["lift"] = time.perf_counter() - t_lift
    meta = _frame_meta(rec, coll, intr, res, grav, ann, metric_scale, truth)
    meta["incomplete_categories"] = F.incomplete_categories(rec.annotations, ann.crowd, cfg)
    if est_name == "geometric":
        meta["foot_border_margin"] = float(cfg["foot_border_margin"])
    fid = unit_key(rec.image_id)  # no folder name: a renamed or moved copy gives the same bytes
    return Frame(fid, rgb, depth, cam, objects, surfaces, source="image", scene_id=fid, meta=_jsonable(meta))


def _annotated(rec: ImageRecord, W: int, H: int, cfg: dict[str, Any]) -> _Annotated:
    """Masks of every annotation; things become candidates (too small, overlapping or incomplete
    categories dropped with a reason), stuff becomes ground or support; DropUnit when too few are left."""
    pan = read_panoptic_ids(rec.panoptic_png, W, H, rec.image_id) if rec.panoptic_png is not None else None
    out = _Annotated(ground=np.zeros((H, W), bool))
    cands, ground = out.cands, out.ground
    wanted = set(cfg["categories"]) if cfg["categories"] else None
    for ann in rec.annotations:
        mask, is_seg = annotation_mask(ann, rec, W, H, pan)  # raises DropUnit for out-of-image annotations
        if not ann.isthing:
            kind = stuff_kind(ann.category)
            if kind == "ground":
                ground |= mask
            elif kind == "support":
                out.support_stuff.append((ann.category, mask))
            continue
        if ann.iscrowd:
            out.crowd.add(ann.category)
            continue
        if wanted is not None and ann.category not in wanted:
            out.ignored[ann.category] = out.ignored.get(ann.category, 0) + 1
            continue
        bb = (
            ann.bbox
            if not rec.meta.get("normalised_boxes")
            else (ann.bbox[0] * W, ann.bbox[1] * H, ann.bbox[2] * W, ann.bbox[3] * H)
        )
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
        F.complete_categories(cands, out.crowd)
    out.live = [c for c in cands if c.reason is None]
    if len(out.live) < cfg["min_objects"]:
        raise DropUnit("too_few_objects", f"{rec.image_id}: {len(out.live)} usable annotated objects before depth")
    return out


def _camera_prior(
    rec: ImageRecord,
    intr: Intrinsics,
    ann: _Annotated,
    cfg: dict[str, Any],
    est_name: str,
    est: Any,
    truth: dict[str, int],
    H: int,
    W: int,
) -> tuple[Any, float, float, dict[str, Any], dict[int, int]]:
    """What the depth estimator is told: the camera prior (for geometric depth, fitted to the photo's objects
    of known size), masks with ids; also the camera height and pitch, the metric-scale verdict and the ids."""
    from refspatial_gen.depth import CameraPrior

    dopts = cfg.get("depth") or {}
    # the camera prior: the depth section's own camera_height/pitch_deg win over the source-level prior
    cam_h = float(dopts.get("camera_height") or cfg["camera_height"])
    pitch = float(np.deg2rad(dopts["pitch_deg"] if dopts.get("pitch_deg") is not None else cfg["camera_pitch_deg"]))
    metric_scale: dict[str, Any] = {"source": "measured", "status": "consistent", "reliable": True}
    if est_name == "geometric":  # the photo's own camera, fitted to its objects of known size
        from refspatial_gen.sources.image.truthcheck import fit_photo_camera

        # every annotated object may testify, also those too small to become objects (distant people
        # near the horizon are what pins the pitch down)
        fit = fit_photo_camera(
            [c for c in ann.cands if c.reason in (None, "too_small")], H, W, intr.fy, intr.cy, cam_h, pitch, cfg
        )
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
    live, ground = ann.live, ann.ground
    ids = {id(c): k + 1 for k, c in enumerate(live)}
    prior = CameraPrior(
        W,
        H,
        intr.fx,
        intr.fy,
        intr.cx,
        intr.cy,
        cam_h,
        pitch,
        depth_path=depth_path,
        depth_scale=rec.meta.get("depth_scale"),
        masks=[(ids[id(c)], c.mask) for c in live],
        categories={ids[id(c)]: c.category for c in live},
        ground_mask=ground if ground.any() else None,
    )
    return prior, cam_h, pitch, metric_scale, ids


def _contact_notes(live: list[F.Candidate], ids: dict[int, int], res: Any, cfg: dict[str, Any]) -> None:
    """The depth estimator's notes per object (what it rests on or stands behind, a contact cut by the
    image edge, no ground contact) into the candidates' provenance; drops where the contact is unseen."""
    for c in live:
        note = res.meta.get("objects", {}).get(str(ids[id(c)]))
        if note is not None:
            c.provenance["contact"] = note.get("contact")
            kind, _, other = str(note.get("contact")).partition(":")
            if kind in ("support", "behind") and other.isdigit():  # the estimator's id -> the annotation
                o = live[int(other) - 1]
                c.provenance["rests_on" if kind == "support" else "behind"] = {
                    "annotation_id": o.ann_id,
                    "category": o.category,
                }
            if note.get("truncated"):
                c.provenance["contact_truncated"] = True
                if not cfg["keep_truncated_contacts"]:
                    F.drop(c, "contact_not_visible")
            if note.get("contact") == "none":
                F.drop(c, note.get("reason", "no_ground_contact"))


def _world_frame(
    depth: np.ndarray,
    intr: Intrinsics,
    prior: Any,
    cam_h: float,
    pitch: float,
    est_name: str,
    cfg: dict[str, Any],
    rng: np.random.Generator,
) -> tuple[Any, Camera]:
    """Gravity (the prior for geometric depth, else a RANSAC floor/table plane, or none) and the camera
    placed in the gravity-aligned world frame."""
    from refspatial_gen.sources.image.gravity import GravityEstimate, estimate_gravity, world_from_cam

    H, W = depth.shape
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
        pts = np.stack(
            [(us[ok] + 0.5 - intr.cx) * z[ok] / intr.fx, (vs[ok] + 0.5 - intr.cy) * z[ok] / intr.fy, z[ok]], axis=1
        )
        g = estimate_gravity(pts, rng, prior_up, cfg["max_tilt_deg"])
        if g is None:
            grav = GravityEstimate(prior_up, False, "unknown", None, detail={"why": "no horizontal plane found"})
        else:
            grav = g
            grav.detail["pixels"] = (us[ok], vs[ok])
    elif mode == "prior":
        grav = GravityEstimate(
            prior_up, True, "prior", cam_h, detail={"pitch_deg": round(float(np.rad2deg(pitch)), 4), "roll_deg": 0.0}
        )
    else:
        grav = GravityEstimate(prior_up, False, "unknown", None, detail={"why": "gravity: none"})
    T = world_from_cam(grav.up_cam, grav.camera_height)
    cam = Camera(W, H, intr.fx, intr.fy, intr.cx, intr.cy, T, gravity_known=grav.known)
    return grav, cam


def _checked_objects(
    rec: ImageRecord, ann: _Annotated, cfg: dict[str, Any], est_name: str, truth: dict[str, int]
) -> list[F.Candidate]:
    """The truth checks on the lifted boxes (sizes, boxes passing through each other, instance spread and
    count, complete categories); DropUnit when too many or too few objects are left."""
    from refspatial_gen.sources.image.truthcheck import check_sizes

    cands = ann.cands
    check_sizes(cands, cfg, est_name != "geometric", truth)
    if est_name == "geometric" and cfg["max_box_overlap"] < 1.0:
        from refspatial_gen.sources.image.truthcheck import check_interpenetration

        check_interpenetration(cands, float(cfg["max_box_overlap"]), truth)
    F.instances_not_spread(cands, cfg["min_instance_spread"])
    F.too_many_instances(cands, cfg["max_instances_per_category"])
    if cfg["complete_categories"]:
        F.complete_categories(cands, ann.crowd)
    final = [c for c in cands if c.reason is None]
    if len(final) > cfg["max_objects"]:
        raise DropUnit("too_many_objects", f"{rec.image_id}: {len(final)} objects > max_objects")
    if len(final) < cfg["min_objects"]:
        raise DropUnit(
            "too_few_objects", f"{rec.image_id}: {len(final)} objects after lifting (dropped: {F.drop_counts(cands)})"
        )
    return final


def _objects(final: list[F.Candidate], coll: Collection, res: Any) -> list[ObjectInstance]:
    """The kept candidates as the frame's objects, ids from 1 in candidate order."""
    objects: list[ObjectInstance] = []
    for k, c in enumerate(final):
        ys, xs = np.nonzero(c.mask)
        bbox2d = (float(xs.min()), float(ys.min()), float(xs.max() + 1), float(ys.max() + 1))
        prov = {
            "source": "image",
            "format": coll.format,
            "annotation_id": c.ann_id,
            "depth": res.origin,
            **c.provenance,
        }
        objects.append(
            ObjectInstance(
                id=k + 1,
                category=c.category,
                box=c.box,
                mask=RLE.encode(c.mask),
                bbox2d=bbox2d,
                visible_fraction=1.0,
                provenance=prov,
            )
        )
    return objects


def _frame_meta(
    rec: ImageRecord,
    coll: Collection,
    intr: Intrinsics,
    res: Any,
    grav: Any,
    ann: _Annotated,
    metric_scale: dict[str, Any],
    truth: dict[str, int],
) -> dict[str, Any]:
    """What the frame records about how it was made: intrinsics, depth, gravity, drops and truth counts."""
    cands = ann.cands
    grav_meta = {
        "origin": grav.origin,
        "known": grav.known,
        "camera_height": None if grav.camera_height is None else round(float(grav.camera_height), 4),
        **{k: v for k, v in grav.detail.items() if k != "pixels"},
    }
    return {
        "image_id": rec.image_id,
        "image_file": rec.file.name,
        "annotation_format": coll.format,
        "intrinsics": intr.meta(),
        "depth": {
            "origin": res.origin,
            "is_metric": res.is_metric,
            **{k: v for k, v in res.meta.items() if k != "objects"},
        },
        "gravity": grav_meta,
        "dropped_objects": F.drop_counts(cands),
        "dropped_object_list": [
            {"annotation_id": c.ann_id, "category": c.category, "reason": c.reason}
            for c in cands
            if c.reason is not None
        ],
        "crowd_categories": sorted(ann.crowd),
        "ignored_categories": dict(sorted(ann.ignored.items())),
        "metric_scale": metric_scale,
        "truth": dict(sorted(truth.items())),
    }


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
