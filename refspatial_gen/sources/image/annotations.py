"""Annotated photo collections -> one in-memory index: images, their object annotations, optional depth/K.

Readers: COCO instances (polygons, compressed and uncompressed RLE), COCO panoptic (PNG + segments),
OpenImages (box CSV, optional mask CSV + mask PNGs) and SUN RGB-D 2D boxes (folders with image.jpg,
depth.png, annotation.json; only the 2D boxes and K are read, never the 3D ground truth). Masks are
materialised per image, lazily, by `annotation_mask`, which also validates that the annotation lies
inside the image (else the whole image is dropped: `annotation_out_of_bounds`).
"""

from __future__ import annotations

import csv
import json
import os
from dataclasses import dataclass, field
from functools import lru_cache
from pathlib import Path
from typing import Any

import numpy as np

from refspatial_gen.core.errors import DropUnit

FORMATS = ("auto", "coco", "coco_panoptic", "openimages", "sunrgbd")
IMAGE_EXTS = (".jpg", ".jpeg", ".png", ".bmp", ".webp")
BOUNDS_TOLERANCE_PX = 1.0  # annotations may touch the border, rounding included; more is an error

# COCO panoptic "stuff" classes that are ground (objects standing there meet the ground plane) or supports
GROUND_STUFF_PREFIXES = ("floor", "road", "pavement", "grass", "dirt", "sand", "playingfield", "snow",
                         "gravel", "rug", "platform", "railroad")
SUPPORT_STUFF_PREFIXES = ("table", "counter", "shelf", "desk")


@dataclass
class Annotation:
    """One annotated object (or stuff region). `bbox` is (x0, y0, x1, y1) in continuous pixel coordinates."""

    ann_id: str
    category: str
    bbox: tuple[float, float, float, float]
    kind: str  # "polygon" | "rle" | "box" | "panoptic" | "mask_png"
    data: Any = None  # polygons | COCO RLE dict | panoptic segment id | mask PNG path
    iscrowd: bool = False
    isthing: bool = True
    attributes: dict[str, str] = field(default_factory=dict)


@dataclass
class ImageRecord:
    image_id: str
    file: Path
    width: int | None
    height: int | None
    annotations: list[Annotation]
    depth_file: Path | None = None
    intrinsics: tuple[float, float, float, float] | None = None  # fx, fy, cx, cy (pixel u spans [u, u+1))
    panoptic_png: Path | None = None
    meta: dict[str, Any] = field(default_factory=dict)


@dataclass
class Collection:
    root: Path
    format: str
    images: dict[str, ImageRecord]

    def ids(self) -> list[str]:
        return sorted(self.images)


# ----------------------------------------------------------------------------------------------- detection


def _json_files(root: Path) -> list[Path]:
    return sorted(p for p in root.iterdir() if p.suffix == ".json" and p.is_file())


def _peek_json(path: Path) -> dict | list | None:
    try:
        with open(path, "r", encoding="utf-8") as f:
            return json.load(f)
    except (OSError, json.JSONDecodeError):
        return None


def detect_format(root: Path) -> str:
    """Guess the annotation format of a folder (explicit `format:` in the recipe skips this)."""
    if not root.is_dir():
        raise FileNotFoundError(f"input folder {root} does not exist")
    subdirs = sorted(p for p in root.iterdir() if p.is_dir())
    if any((d / "annotation.json").is_file() and (d / "image.jpg").is_file() for d in subdirs):
        return "sunrgbd"
    if any(p.suffix == ".csv" for p in root.iterdir()):
        for p in sorted(root.glob("*.csv")):
            with open(p, "r", encoding="utf-8") as f:
                head = f.readline()
            if "XMin" in head or "BoxXMin" in head:
                return "openimages"
    found = None
    for p in _json_files(root):
        d = _peek_json(p)
        if isinstance(d, dict) and "annotations" in d and d["annotations"]:
            if "segments_info" in d["annotations"][0]:
                return "coco_panoptic"
            if "images" in d and "categories" in d:
                found = "coco"
    if found:
        return found
    raise DropUnit("unknown_annotation_format", f"no COCO/panoptic/OpenImages/SUN RGB-D annotations in {root}")


def _images_dir(root: Path, hint: str | None) -> Path:
    if hint:
        return root / hint
    for name in ("images", "input_images", "train2017", "val2017", "image"):
        if (root / name).is_dir():
            return root / name
    return root


# ----------------------------------------------------------------------------------------------- readers


def _xywh(b) -> tuple[float, float, float, float]:
    x, y, w, h = (float(v) for v in b)
    return x, y, x + w, y + h


def read_coco(root: Path, annotations: str | None = None, images_dir: str | None = None) -> Collection:
    ann_file = root / annotations if annotations else None
    if ann_file is None:
        cands = []
        for p in _json_files(root):
            d = _peek_json(p)
            if isinstance(d, dict) and "images" in d and "categories" in d and "annotations" in d:
                if not (d["annotations"] and "segments_info" in d["annotations"][0]):
                    cands.append((p, d))
        if not cands:
            raise DropUnit("annotations_missing", f"no COCO instances JSON in {root}")
        ann_file, data = cands[0]
    else:
        data = _peek_json(ann_file)
        if not isinstance(data, dict):
            raise DropUnit("annotations_unreadable", str(ann_file))
    img_dir = _images_dir(root, images_dir)
    cats = {int(c["id"]): str(c["name"]) for c in data.get("categories", [])}
    things = {int(c["id"]): bool(c.get("isthing", 1)) for c in data.get("categories", [])}
    images: dict[str, ImageRecord] = {}
    for im in data["images"]:
        iid = str(im["id"])
        images[iid] = ImageRecord(iid, img_dir / im["file_name"], int(im["width"]), int(im["height"]), [],
                                  meta={"file_name": im["file_name"], "license": im.get("license")})
    for a in sorted(data["annotations"], key=lambda a: (str(a["image_id"]), int(a["id"]))):
        rec = images.get(str(a["image_id"]))
        if rec is None:
            continue
        seg = a.get("segmentation")
        if isinstance(seg, list):
            kind, payload = ("polygon", seg) if seg else ("box", None)
        elif isinstance(seg, dict):
            kind, payload = "rle", seg
        else:
            kind, payload = "box", None
        cid = int(a["category_id"])
        rec.annotations.append(Annotation(str(a["id"]), cats.get(cid, str(cid)), _xywh(a["bbox"]), kind, payload,
                                          bool(a.get("iscrowd", 0)), things.get(cid, True)))
    return Collection(root, "coco", images)


def read_coco_panoptic(root: Path, annotations: str | None = None, images_dir: str | None = None) -> Collection:
    data = None
    if annotations:
        data = _peek_json(root / annotations)
    else:
        for p in _json_files(root):
            d = _peek_json(p)
            if isinstance(d, dict) and d.get("annotations") and "segments_info" in d["annotations"][0]:
                data = d
                break
    if not isinstance(data, dict):
        raise DropUnit("annotations_missing", f"no COCO panoptic JSON in {root}")
    cat_list = data.get("categories") or []
    if not cat_list and (root / "panoptic_coco_categories.json").is_file():
        cat_list = _peek_json(root / "panoptic_coco_categories.json") or []
    cats = {int(c["id"]): (str(c["name"]), bool(c.get("isthing", 1))) for c in cat_list}
    img_dir = _images_dir(root, images_dir)
    png_dirs = [d for d in sorted(root.iterdir()) if d.is_dir() and d != img_dir
                and any(p.suffix == ".png" for p in d.iterdir())]
    images: dict[str, ImageRecord] = {}
    for im in data["images"]:
        iid = str(im["id"])
        images[iid] = ImageRecord(iid, img_dir / im["file_name"], int(im["width"]), int(im["height"]), [],
                                  meta={"file_name": im["file_name"], "license": im.get("license")})
    for a in sorted(data["annotations"], key=lambda a: str(a["image_id"])):
        rec = images.get(str(a["image_id"]))
        if rec is None:
            continue
        png = next((d / a["file_name"] for d in png_dirs if (d / a["file_name"]).is_file()), None)
        rec.panoptic_png = png
        for s in sorted(a["segments_info"], key=lambda s: int(s["id"])):
            name, isthing = cats.get(int(s["category_id"]), (str(s["category_id"]), True))
            rec.annotations.append(Annotation(str(s["id"]), name, _xywh(s["bbox"]), "panoptic", int(s["id"]),
                                              bool(s.get("iscrowd", 0)), isthing))
    return Collection(root, "coco_panoptic", images)


def _read_csv(path: Path) -> list[dict[str, str]]:
    with open(path, "r", encoding="utf-8", newline="") as f:
        return list(csv.DictReader(f))


def read_openimages(root: Path, annotations: str | None = None, images_dir: str | None = None) -> Collection:
    """OpenImages V4+ CSVs: boxes (ImageID, LabelName, XMin, XMax, YMin, YMax, Is*), optional masks
    (MaskPath, ImageID, LabelName, BoxXMin...) with PNGs under `masks/`, and class descriptions
    (LabelName,DisplayName; with or without a header). Coordinates are normalised to [0, 1]."""
    csvs = sorted(root.glob("*.csv"))
    names: dict[str, str] = {}
    box_rows: list[dict[str, str]] = []
    mask_rows: list[dict[str, str]] = []
    for p in csvs:
        with open(p, "r", encoding="utf-8") as f:
            head = f.readline()
        if "MaskPath" in head:
            mask_rows.extend(_read_csv(p))
        elif "XMin" in head:
            box_rows.extend(_read_csv(p))
        else:
            with open(p, "r", encoding="utf-8", newline="") as f:
                for row in csv.reader(f):
                    if len(row) >= 2 and row[0] != "LabelName":
                        names[row[0]] = row[1]
    if annotations:
        box_rows = _read_csv(root / annotations)
    img_dir = _images_dir(root, images_dir)
    mask_dir = root / "masks"
    files = {p.stem: p for p in sorted(img_dir.iterdir()) if p.suffix.lower() in IMAGE_EXTS} if img_dir.is_dir() else {}
    images: dict[str, ImageRecord] = {}

    def rec_for(iid: str) -> ImageRecord:
        if iid not in images:
            images[iid] = ImageRecord(iid, files.get(iid, img_dir / f"{iid}.jpg"), None, None, [])
        return images[iid]

    if mask_rows:
        for k, r in enumerate(sorted(mask_rows, key=lambda r: (r["ImageID"], r["MaskPath"]))):
            label = r["LabelName"]
            bb = tuple(float(r[c]) for c in ("BoxXMin", "BoxYMin", "BoxXMax", "BoxYMax"))
            rec_for(r["ImageID"]).annotations.append(Annotation(
                f"m{k}", names.get(label, label), bb, "mask_png", mask_dir / r["MaskPath"],
                attributes={}))
    else:
        for k, r in enumerate(sorted(box_rows, key=lambda r: (r["ImageID"], r["LabelName"], r["XMin"], r["YMin"]))):
            label = r["LabelName"]
            bb = (float(r["XMin"]), float(r["YMin"]), float(r["XMax"]), float(r["YMax"]))
            rec_for(r["ImageID"]).annotations.append(Annotation(
                f"b{k}", names.get(label, label), bb, "box", None, iscrowd=r.get("IsGroupOf", "0") == "1",
                attributes={}))
    for rec in images.values():
        rec.meta["normalised_boxes"] = True
    return Collection(root, "openimages", images)


def read_sunrgbd(root: Path, annotations: str | None = None, images_dir: str | None = None) -> Collection:
    """SUN RGB-D folders as plain images: 2D boxes (1-based MATLAB -> 0-based), K and the depth path.
    The 3D boxes and Rtilt are deliberately not read (they are the ground truth of the evaluation)."""
    images: dict[str, ImageRecord] = {}
    for d in sorted(p for p in root.iterdir() if p.is_dir() and (p / "annotation.json").is_file()):
        a = _peek_json(d / "annotation.json")
        if not isinstance(a, dict):
            raise DropUnit("annotations_unreadable", str(d / "annotation.json"))
        K = np.asarray(a["K"], float)
        rec = ImageRecord(d.name, d / a.get("image", "image.jpg"), int(a["width"]), int(a["height"]), [],
                          depth_file=d / a.get("depth", "depth.png"),
                          # the annotation's K is in 0-based pixel centres: +0.5 to the pixel-edge convention
                          intrinsics=(float(K[0, 0]), float(K[1, 1]), float(K[0, 2]) + 0.5, float(K[1, 2]) + 0.5),
                          meta={"depth_scale": float(a.get("depth_scale", 1000.0))})
        for k, o in enumerate(a["objects"]):
            x0, y0, x1, y1 = (float(v) for v in o["bbox2d_xyxy"])
            # 1-based pixel centres -> continuous 0-based coordinates: first pixel x0 spans [x0-1, x0)
            rec.annotations.append(Annotation(str(k), str(o["category"]), (x0 - 1.0, y0 - 1.0, x1, y1), "box"))
        images[d.name] = rec
    return Collection(root, "sunrgbd", images)


READERS = {"coco": read_coco, "coco_panoptic": read_coco_panoptic, "openimages": read_openimages,
           "sunrgbd": read_sunrgbd}


def _mtime_key(root: Path) -> tuple:
    return tuple(sorted((p.name, p.stat().st_mtime_ns) for p in root.iterdir() if p.is_file()))


@lru_cache(maxsize=8)
def _load_cached(root: str, fmt: str, annotations: str | None, images_dir: str | None, stamp: tuple) -> Collection:
    return READERS[fmt](Path(root), annotations, images_dir)


def load_collection(root: str | Path, fmt: str = "auto", annotations: str | None = None,
                    images_dir: str | None = None) -> Collection:
    """Read (once per process; cached on the folder's file mtimes) an annotated collection."""
    root = Path(root).resolve()
    if fmt == "auto":
        fmt = detect_format(root)
    if fmt not in READERS:
        raise ValueError(f"unknown annotation format {fmt!r} (known: {', '.join(sorted(READERS))})")
    return _load_cached(str(root), fmt, annotations, images_dir, _mtime_key(root))


# ----------------------------------------------------------------------------------------------- masks


def _check_bounds(ann: Annotation, extent: tuple[float, float, float, float], width: int, height: int,
                  image_id: str) -> None:
    x0, y0, x1, y1 = extent
    t = BOUNDS_TOLERANCE_PX
    if x0 < -t or y0 < -t or x1 > width + t or y1 > height + t or not np.all(np.isfinite(extent)):
        raise DropUnit("annotation_out_of_bounds",
                       f"image {image_id}: annotation {ann.ann_id} ({ann.category}) spans "
                       f"[{x0:.1f}, {y0:.1f}, {x1:.1f}, {y1:.1f}] outside the {width}x{height} image")


def resolved_bbox(ann: Annotation, rec: ImageRecord, width: int, height: int) -> tuple[float, float, float, float]:
    """The annotation's box in pixels (OpenImages stores normalised boxes), checked against the image."""
    bb = ann.bbox
    if rec.meta.get("normalised_boxes"):
        bb = (bb[0] * width, bb[1] * height, bb[2] * width, bb[3] * height)
    _check_bounds(ann, bb, width, height, rec.image_id)
    return bb


def read_panoptic_ids(path: Path, width: int, height: int, image_id: str) -> np.ndarray:
    from refspatial_gen.core.serialize import decode_image

    try:
        img = decode_image(Path(path).read_bytes())  # a label map: never turned by an EXIF tag
    except (OSError, ValueError) as e:
        raise DropUnit("annotation_unreadable", f"image {image_id}: panoptic PNG {path} could not be decoded") from e
    if img.shape[:2] != (height, width):
        raise DropUnit("annotation_size_mismatch",
                       f"image {image_id}: panoptic PNG is {img.shape[1]}x{img.shape[0]}, image {width}x{height}")
    rgb = img.astype(np.int64)
    return rgb[..., 0] + 256 * rgb[..., 1] + 256 * 256 * rgb[..., 2]


def annotation_mask(ann: Annotation, rec: ImageRecord, width: int, height: int,
                    panoptic_ids: np.ndarray | None = None) -> tuple[np.ndarray, bool]:
    """The annotation's visible mask (bool HxW) and whether it is a true segmentation (False: box only).

    Raises DropUnit for an annotation outside the image or of the wrong size (the whole image is dropped:
    a misregistered annotation file would make every answer about that image wrong)."""
    import cv2

    from refspatial_gen.sources.image.rle import box_mask, polygons_extent, polygons_to_mask, rle_from_coco

    bb = resolved_bbox(ann, rec, width, height)
    if ann.kind == "polygon":
        _check_bounds(ann, polygons_extent(ann.data), width, height, rec.image_id)
        return polygons_to_mask(ann.data, height, width), True
    if ann.kind == "rle":
        try:
            return rle_from_coco(ann.data, height, width).decode(), True
        except (ValueError, KeyError, TypeError) as e:
            raise DropUnit("annotation_size_mismatch", f"image {rec.image_id}: annotation {ann.ann_id}: {e}") from e
    if ann.kind == "panoptic":
        if panoptic_ids is None:
            raise DropUnit("annotation_missing", f"image {rec.image_id}: no panoptic PNG")
        return panoptic_ids == int(ann.data), True
    if ann.kind == "mask_png":
        m = cv2.imread(str(ann.data), cv2.IMREAD_GRAYSCALE)
        if m is None:
            raise DropUnit("annotation_unreadable", f"image {rec.image_id}: mask {ann.data} could not be decoded")
        if m.shape != (height, width):  # OpenImages masks come at their own resolution: resample to the image
            m = cv2.resize(m, (width, height), interpolation=cv2.INTER_NEAREST)
        return m > 127, True
    return box_mask(bb, height, width), False


def list_image_files(root: Path) -> list[Path]:
    return sorted(p for p in root.iterdir() if p.suffix.lower() in IMAGE_EXTS and os.path.isfile(p))
