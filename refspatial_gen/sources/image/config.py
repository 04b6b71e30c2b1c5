"""The image source's recipe config: its fields (checked before any work), defaults and depth estimator."""

from __future__ import annotations

from functools import lru_cache
from typing import Any

from refspatial_gen.perception.config import perception_field
from refspatial_gen.schema import Field
from refspatial_gen.sources.image.annotations import FORMATS
from refspatial_gen.sources.image.intrinsics import MODES


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


def _names_check(v: Any) -> str | None:
    """A list of category names: a number or a nested list would never match a category and pass silently."""
    bad = [x for x in v if not (isinstance(x, str) and x.strip())]
    return f"must be a list of category names, got {bad[0]!r}" if bad else None


CONFIG_FIELDS: dict[str, Field] = {
    "format": Field(str, default="auto", choices=FORMATS, doc="annotation format of the input folder"),
    "annotations": Field(str, default=None, doc="annotation file inside the input folder (default: detected)"),
    "images_dir": Field(str, default=None, doc="image folder inside the input folder (default: detected)"),
    "depth": Field(
        dict,
        default={"estimator": "geometric"},
        check=_depth_check,
        doc="depth estimator: {estimator: NAME, ...its options}",
    ),
    "intrinsics": Field(str, default="auto", choices=MODES, doc="provided | exif | fov prior | auto (in that order)"),
    "hfov_deg": Field(float, default=60.0, min=5.0, max=170.0, doc="horizontal field of view prior"),
    "gravity": Field(
        str,
        default="auto",
        choices=("auto", "plane", "prior", "none"),
        doc="auto: the depth prior for geometric depth, else a RANSAC floor/table plane",
    ),
    "camera_height": Field(float, default=1.5, min=0.05, doc="camera height prior (m)"),
    "camera_pitch_deg": Field(float, default=0.0, min=-60.0, max=80.0, doc="downward pitch prior (deg)"),
    "max_tilt_deg": Field(float, default=40.0, min=1.0, max=89.0, doc="largest tilt of a plane taken as horizontal"),
    "categories": Field(
        list, default=None, check=_names_check, doc="only these categories become objects (default: all things)"
    ),
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
    "keep_truncated_contacts": Field(
        bool, default=False, doc="geometric depth: keep objects cut by the bottom edge (contact unseen)"
    ),
    "min_objects": Field(int, default=2, min=1),
    "max_objects": Field(int, default=40, min=1),
    # truth checks (docs/quality.md): the photo's camera fitted to its objects, sizes against their ranges
    "fit_camera": Field(
        bool,
        default=True,
        doc="geometric depth: fit camera height and pitch per photo to the "
        "ground-standing objects of known size (the camera above is the prior)",
    ),
    "fit_pitch_range_deg": Field(list, default=[-15.0, 45.0], check=_pair_check, doc="pitch search range (deg)"),
    "fit_height_range": Field(list, default=[0.3, 30.0], check=_pair_check, doc="camera height search range (m)"),
    "fit_min_inlier_share": Field(
        float,
        default=0.6,
        min=0.0,
        max=1.0,
        doc="share of those objects that must fit their range for a reliable metric scale",
    ),
    "fit_min_anchors": Field(
        int,
        default=2,
        min=1,
        doc="agreeing objects needed before the metric scale counts as verified (one object fits any camera)",
    ),
    "size_check": Field(bool, default=True, doc="remove objects whose lifted box is outside their category's range"),
    "size_tolerance": Field(float, default=0.0, min=0.0, max=1.0, doc="ranges are widened by this fraction"),
    "max_box_overlap": Field(
        float,
        default=0.25,
        min=0.0,
        max=1.0,
        doc="geometric depth: two boxes sharing more of the smaller one's volume pass through "
        "each other; the occluded one is removed (1 = off)",
    ),
    "composite_max_std": Field(
        float,
        default=3.0,
        min=0.0,
        max=255.0,
        doc="drop a photo pasted from several (image_composite): an interior full-height/width band whose "
        "colour spread (channel std, 0..255) stays below this (0 = off; sources/image/composite.py)",
    ),
    "foot_border_margin": Field(
        float,
        default=0.02,
        min=0.0,
        max=0.5,
        doc="geometric depth: an object whose lowest mask row lies within this share of the height of the "
        "bottom edge has no trusted 3D position (its foot may be cut; sources/image/contact.py)",
    ),
    "incomplete_min_instances": Field(
        int,
        default=6,
        min=1,
        doc="a category with this many annotated instances in a photo is not trusted complete: no "
        "superlative, ordinal, count or unique reference over it (qa/faint_photo.py)",
    ),
    "incomplete_categories": Field(
        list,
        default=["person"],
        check=_names_check,
        doc="categories never trusted complete on photos (COCO leaves background people unannotated)",
    ),
    "perception": perception_field(),  # unlabelled photos: annotations from local models (docs/perception.md)
}


def with_defaults(config: dict[str, Any] | None) -> dict[str, Any]:
    cfg = {k: f.default for k, f in CONFIG_FIELDS.items()}
    cfg.update({k: v for k, v in (config or {}).items() if v is not None})
    return cfg


@lru_cache(maxsize=4)
def _estimator(name: str, options: tuple):
    from refspatial_gen.depth import get_estimator

    return get_estimator(name, dict(options))


def estimator_from_config(cfg: dict[str, Any]):
    d = dict(cfg.get("depth") or {"estimator": "geometric"})
    name = d.pop("estimator")
    return name, _estimator(name, tuple(sorted((k, tuple(v) if isinstance(v, list) else v) for k, v in d.items())))
