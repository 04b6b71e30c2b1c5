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

from refspatial_gen.core.errors import DropUnit, InputError
from refspatial_gen.sources.image import checks as C

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
    except (OSError, ValueError, RecursionError):  # ValueError covers JSONDecodeError and UnicodeDecodeError
        return None


def _first_entry(d: dict) -> Any:
    anns = d.get("annotations")
    return anns[0] if isinstance(anns, list) and anns else None


def _is_panoptic(d: Any) -> bool:
    first = _first_entry(d) if isinstance(d, dict) else None
    return isinstance(first, dict) and "segments_info" in first


def _is_coco(d: Any) -> bool:
    """A COCO instances file (its lists are checked by the reader, which names what is wrong)."""
    return isinstance(d, dict) and "images" in d and "annotations" in d and not _is_panoptic(d)


def _csv_head(p: Path) -> str:
    try:
        with open(p, "r", encoding="utf-8") as f:
            return f.readline()
    except (OSError, UnicodeDecodeError):
        return ""


def detect_format(root: Path) -> str:
    """Guess the annotation format of a folder (explicit `format:` in the recipe skips this)."""
    if not root.is_dir():
        raise InputError(str(root), "input folder does not exist" if not root.exists() else "input is not a folder")
    subdirs = sorted(p for p in root.iterdir() if p.is_dir())
    if any((d / "annotation.json").is_file() and (d / "image.jpg").is_file() for d in subdirs):
        return "sunrgbd"
    for p in sorted(root.glob("*.csv")):
        head = _csv_head(p)
        if "XMin" in head or "BoxXMin" in head:
            return "openimages"
    found = None
    for p in _json_files(root):
        d = _peek_json(p)
        if _is_panoptic(d):
            return "coco_panoptic"
        if _is_coco(d):
            found = "coco"
    if found:
        return found
    for p in _json_files(root):  # nothing recognised: a broken JSON file is the likely reason, say which
        if _peek_json(p) is None:
            C.load_json_file(p)  # raises InputError with the parse error
    raise InputError(str(root), "no COCO / COCO panoptic / OpenImages / SUN RGB-D annotations found")


def _images_dir(root: Path, hint: str | None) -> Path:
    if hint:
        return root / hint
    for name in ("images", "input_images", "train2017", "val2017", "image"):
        if (root / name).is_dir():
            return root / name
    return root


# ----------------------------------------------------------------------------------------------- readers


def _invalid(images: dict[str, ImageRecord], iid: str, img_dir: Path, bad: C.Bad) -> None:
    """Mark an image's record invalid (created when the entry itself was unusable); the first problem wins."""
    rec = images.get(iid)
    if rec is None:
        rec = images[iid] = ImageRecord(iid, img_dir / "(invalid)", None, None, [])
    rec.meta.setdefault("invalid", (bad.reason, bad.detail))


def _image_records(entries: list, img_dir: Path, where: str) -> dict[str, ImageRecord]:
    """COCO `images` entries -> records; a malformed entry yields an invalid record (dropped when loaded)."""
    images: dict[str, ImageRecord] = {}
    for k, im in enumerate(entries):
        iid = C.entry_id(im.get("id")) if isinstance(im, dict) else None
        if iid is None:
            _invalid(images, f"#images[{k}]", img_dir, C.Bad("annotation_invalid", f"{where} images[{k}] has no usable id"))
            continue
        if iid in images:
            _invalid(images, iid, img_dir, C.Bad("annotation_invalid", f"{where}: image id {iid} listed twice"))
            continue
        try:
            file = C.relative_file(im.get("file_name"), img_dir, f"image {iid} file_name")
            w, h = C.positive_int(im.get("width"), f"image {iid} width"), C.positive_int(im.get("height"), f"image {iid} height")
        except C.Bad as bad:
            _invalid(images, iid, img_dir, bad)
            continue
        images[iid] = ImageRecord(iid, file, w, h, [], meta={"file_name": im["file_name"], "license": im.get("license")})
    return images


def _categories(entries: list) -> dict[int, tuple[str, bool]]:
    """id -> (name, isthing); malformed entries are left out (annotations naming them become invalid)."""
    out: dict[int, tuple[str, bool]] = {}
    for c in entries:
        if isinstance(c, dict) and isinstance(c.get("id"), int) and not isinstance(c.get("id"), bool) \
                and isinstance(c.get("name"), str):
            out[c["id"]] = (c["name"], bool(c.get("isthing", 1)))
    return out


def _category(cats: dict[int, tuple[str, bool]], v: Any, what: str) -> tuple[int, str, bool]:
    cid = C.int_id(v, f"{what} category_id")
    if cid not in cats:
        raise C.Bad("annotation_invalid", f"{what} category_id {cid} is not in the categories")
    return cid, *cats[cid]


def _coco_annotation(a: dict, cats: dict, what: str) -> tuple[int, Annotation]:
    aid = C.int_id(a.get("id"), f"{what} id")
    kind, payload = C.segmentation(a.get("segmentation"))
    _, name, isthing = _category(cats, a.get("category_id"), what)
    return aid, Annotation(str(aid), name, C.bbox_xywh(a.get("bbox"), f"{what} bbox"), kind, payload,
                           C.flag(a.get("iscrowd"), f"{what} iscrowd"), isthing)


def _attach(images: dict[str, ImageRecord], entries: list, img_dir: Path, where: str, parse) -> None:
    """Annotations -> their images, sorted by annotation id; `parse(entry, what)` -> (sort key, [Annotation])."""
    per_image: dict[str, list] = {}
    for k, a in enumerate(entries):
        iid = C.entry_id(a.get("image_id")) if isinstance(a, dict) else None
        if iid is None:
            _invalid(images, f"#annotations[{k}]", img_dir,
                     C.Bad("annotation_invalid", f"{where} annotations[{k}] has no usable image_id"))
            continue
        rec = images.get(iid)
        if rec is None or rec.meta.get("invalid"):
            continue  # an image this file does not list (a subset), or one already dropped
        try:
            key, anns = parse(a, f"image {iid} annotation {a.get('id', k)}")
        except C.Bad as bad:
            _invalid(images, iid, img_dir, bad)
            continue
        per_image.setdefault(iid, []).append((key, anns))
    for iid, items in per_image.items():
        if not images[iid].meta.get("invalid"):
            for _, anns in sorted(items, key=lambda t: t[0]):
                images[iid].annotations.extend(anns)


def _top_level(root: Path, annotations: str | None, pick, what: str) -> tuple[Path, dict]:
    """The annotation file (named, or the first in `root` that `pick` accepts) and its data, checked."""
    if annotations:
        ann_file = root / annotations
        data = C.load_json_file(ann_file)
    else:
        cands = [p for p in _json_files(root) if pick(_peek_json(p))]
        if not cands:
            raise InputError(str(root), f"no {what} JSON found")
        ann_file = cands[0]
        data = C.load_json_file(ann_file)
    if not isinstance(data, dict):
        raise InputError(str(ann_file), f"a {what} file must be a JSON object, got {type(data).__name__}")
    return ann_file, data


def read_coco(root: Path, annotations: str | None = None, images_dir: str | None = None) -> Collection:
    ann_file, data = _top_level(root, annotations, _is_coco, "COCO instances")
    entries = C.require_list(data, "images", ann_file)
    anns = C.require_list(data, "annotations", ann_file)
    cats = _categories(C.require_list(data, "categories", ann_file))
    img_dir = _images_dir(root, images_dir)
    images = _image_records(entries, img_dir, ann_file.name)

    def parse(a: dict, what: str):
        aid, ann = _coco_annotation(a, cats, what)
        return aid, [ann]

    _attach(images, anns, img_dir, ann_file.name, parse)
    return Collection(root, "coco", images)


def read_coco_panoptic(root: Path, annotations: str | None = None, images_dir: str | None = None) -> Collection:
    ann_file, data = _top_level(root, annotations, _is_panoptic, "COCO panoptic")
    cat_list = C.require_list(data, "categories", ann_file, required=False)
    if not cat_list and (root / "panoptic_coco_categories.json").is_file():
        cat_list = C.load_json_file(root / "panoptic_coco_categories.json")
        if not isinstance(cat_list, list):
            raise InputError(str(root / "panoptic_coco_categories.json"), "must be a JSON list of categories")
    cats = _categories(cat_list)
    img_dir = _images_dir(root, images_dir)
    png_dirs = [d for d in sorted(root.iterdir()) if d.is_dir() and d != img_dir
                and any(p.suffix == ".png" for p in d.iterdir())]
    images = _image_records(C.require_list(data, "images", ann_file), img_dir, ann_file.name)
    pngs: dict[str, Path | None] = {}

    def parse(a: dict, what: str):
        iid = str(C.entry_id(a["image_id"]))
        C.relative_file(a.get("file_name"), root, f"{what} file_name")  # a plain relative name, or the image drops
        names = [C.relative_file(a.get("file_name"), d, f"{what} file_name") for d in png_dirs]
        pngs[iid] = next((p for p in names if p.is_file()), None)
        segs = a.get("segments_info")
        if not isinstance(segs, list):
            raise C.Bad("annotation_invalid", f"{what} segments_info must be a list")
        out = []
        for j, sg in enumerate(segs):
            if not isinstance(sg, dict):
                raise C.Bad("annotation_invalid", f"{what} segments_info[{j}] must be a mapping")
            sid = C.int_id(sg.get("id"), f"{what} segment id")
            _, name, isthing = _category(cats, sg.get("category_id"), f"{what} segment {sid}")
            out.append((sid, Annotation(str(sid), name, C.bbox_xywh(sg.get("bbox"), f"{what} segment {sid} bbox"),
                                        "panoptic", sid, C.flag(sg.get("iscrowd"), f"{what} iscrowd"), isthing)))
        return iid, [ann for _, ann in sorted(out, key=lambda t: t[0])]

    _attach(images, C.require_list(data, "annotations", ann_file), img_dir, ann_file.name, parse)
    for iid, png in pngs.items():
        images[iid].panoptic_png = png
    return Collection(root, "coco_panoptic", images)


def _read_csv(path: Path, required: tuple[str, ...] = ()) -> list[dict[str, str]]:
    try:
        with open(path, "r", encoding="utf-8", newline="") as f:
            reader = csv.DictReader(f)
            missing = [c for c in required if c not in (reader.fieldnames or [])]
            if missing:
                raise InputError(str(path), f"missing column(s) {', '.join(missing)}")
            return list(reader)
    except (UnicodeDecodeError, csv.Error) as e:
        raise InputError(str(path), f"not a readable CSV file ({type(e).__name__})") from None


BOX_COLUMNS = ("ImageID", "LabelName", "XMin", "XMax", "YMin", "YMax")
MASK_COLUMNS = ("MaskPath", "ImageID", "LabelName", "BoxXMin", "BoxYMin", "BoxXMax", "BoxYMax")


def _num(row: dict[str, str], col: str, what: str) -> float:
    try:
        return C.finite(float(row.get(col) or "nan"), f"{what} {col}")
    except ValueError:
        raise C.Bad("annotation_invalid", f"{what} {col} is not a number: {str(row.get(col))[:30]!r}") from None


def read_openimages(root: Path, annotations: str | None = None, images_dir: str | None = None) -> Collection:
    """OpenImages V4+ CSVs: boxes (ImageID, LabelName, XMin, XMax, YMin, YMax, Is*), optional masks
    (MaskPath, ImageID, LabelName, BoxXMin...) with PNGs under `masks/`, and class descriptions
    (LabelName,DisplayName; with or without a header). Coordinates are normalised to [0, 1]."""
    names: dict[str, str] = {}
    box_rows: list[dict[str, str]] = []
    mask_rows: list[dict[str, str]] = []
    for p in sorted(root.glob("*.csv")):
        head = _csv_head(p)
        if "MaskPath" in head:
            mask_rows.extend(_read_csv(p, MASK_COLUMNS))
        elif "XMin" in head:
            box_rows.extend(_read_csv(p, BOX_COLUMNS))
        else:
            try:
                with open(p, "r", encoding="utf-8", newline="") as f:
                    for row in csv.reader(f):
                        if len(row) >= 2 and row[0] != "LabelName":
                            names[row[0]] = row[1]
            except (UnicodeDecodeError, csv.Error) as e:
                raise InputError(str(p), f"not a readable CSV file ({type(e).__name__})") from None
    if annotations:
        box_rows = _read_csv(root / annotations, BOX_COLUMNS)
    img_dir = _images_dir(root, images_dir)
    mask_dir = root / "masks"
    files = {p.stem: p for p in sorted(img_dir.iterdir()) if p.suffix.lower() in IMAGE_EXTS} if img_dir.is_dir() else {}
    images: dict[str, ImageRecord] = {}

    def rec_for(iid: str) -> ImageRecord:
        if iid not in images:
            images[iid] = ImageRecord(iid, files.get(iid, img_dir / f"{iid}.jpg"), None, None, [])
        return images[iid]

    rows = mask_rows if mask_rows else box_rows
    order = (lambda r: (r["ImageID"], r["MaskPath"])) if mask_rows else \
        (lambda r: (r["ImageID"], r["LabelName"], r["XMin"], r["YMin"]))
    for k, r in enumerate(sorted(rows, key=lambda r: tuple(str(x) for x in order(r)))):
        iid = C.entry_id(r["ImageID"])
        if iid is None:
            _invalid(images, f"#rows[{k}]", img_dir, C.Bad("annotation_invalid", f"CSV row {k} has no ImageID"))
            continue
        label = r["LabelName"]
        try:
            if mask_rows:
                bb = tuple(_num(r, c, f"image {iid}") for c in ("BoxXMin", "BoxYMin", "BoxXMax", "BoxYMax"))
                ann = Annotation(f"m{k}", names.get(label, label), bb, "mask_png",
                                 C.relative_file(r["MaskPath"], mask_dir, f"image {iid} MaskPath"), attributes={})
            else:
                bb = (_num(r, "XMin", f"image {iid}"), _num(r, "YMin", f"image {iid}"),
                      _num(r, "XMax", f"image {iid}"), _num(r, "YMax", f"image {iid}"))
                ann = Annotation(f"b{k}", names.get(label, label), bb, "box", None,
                                 iscrowd=r.get("IsGroupOf", "0") == "1", attributes={})
        except C.Bad as bad:
            rec_for(iid).meta.setdefault("invalid", (bad.reason, bad.detail))
            continue
        rec_for(iid).annotations.append(ann)
    for rec in images.values():
        rec.meta["normalised_boxes"] = True
    return Collection(root, "openimages", images)


def _sunrgbd_record(d: Path) -> ImageRecord:
    """One SUN RGB-D folder -> its record; any malformed value makes the record invalid (dropped on load)."""
    rec = ImageRecord(d.name, d / "image.jpg", None, None, [])
    try:
        a = _peek_json(d / "annotation.json")
        if not isinstance(a, dict):
            raise C.Bad("annotation_invalid", f"{d.name}/annotation.json is not a readable JSON object")
        K = np.asarray(a.get("K"), dtype=object)
        if K.shape != (3, 3):
            raise C.Bad("annotation_invalid", f"{d.name}: K must be a 3x3 matrix")
        K = np.array([[C.finite(v, f"{d.name} K") for v in row] for row in K.tolist()])
        scale = C.finite(a.get("depth_scale", 1000.0), f"{d.name} depth_scale")
        if scale <= 0:
            raise C.Bad("annotation_invalid", f"{d.name}: depth_scale must be > 0")
        objects = a.get("objects")
        if not isinstance(objects, list):
            raise C.Bad("annotation_invalid", f"{d.name}: objects must be a list")
        rec = ImageRecord(d.name, C.relative_file(a.get("image", "image.jpg"), d, f"{d.name} image"),
                          C.positive_int(a.get("width"), f"{d.name} width"), C.positive_int(a.get("height"), f"{d.name} height"),
                          [], depth_file=C.relative_file(a.get("depth", "depth.png"), d, f"{d.name} depth"),
                          # the annotation's K is in 0-based pixel centres: +0.5 to the pixel-edge convention
                          intrinsics=(float(K[0, 0]), float(K[1, 1]), float(K[0, 2]) + 0.5, float(K[1, 2]) + 0.5),
                          meta={"depth_scale": scale})
        for k, o in enumerate(objects):
            b = o.get("bbox2d_xyxy") if isinstance(o, dict) else None
            if not isinstance(b, list) or len(b) != 4:
                raise C.Bad("annotation_invalid", f"{d.name}: object {k} bbox2d_xyxy must be [x0, y0, x1, y1]")
            x0, y0, x1, y1 = (C.finite(v, f"{d.name} object {k} bbox2d_xyxy") for v in b)
            if not isinstance(o.get("category"), str):
                raise C.Bad("annotation_invalid", f"{d.name}: object {k} category must be a string")
            # 1-based pixel centres -> continuous 0-based coordinates: first pixel x0 spans [x0-1, x0)
            rec.annotations.append(Annotation(str(k), o["category"], (x0 - 1.0, y0 - 1.0, x1, y1), "box"))
    except C.Bad as bad:
        rec.annotations = []
        rec.meta["invalid"] = (bad.reason, bad.detail)
    return rec


def read_sunrgbd(root: Path, annotations: str | None = None, images_dir: str | None = None) -> Collection:
    """SUN RGB-D folders as plain images: 2D boxes (1-based MATLAB -> 0-based), K and the depth path.
    The 3D boxes and Rtilt are deliberately not read (they are the ground truth of the evaluation)."""
    images: dict[str, ImageRecord] = {}
    for d in sorted(p for p in root.iterdir() if p.is_dir() and (p / "annotation.json").is_file()):
        images[d.name] = _sunrgbd_record(d)
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
        blob = Path(path).read_bytes()
        if not blob:
            raise ValueError("empty file")
        img = decode_image(blob)  # a label map: never turned by an EXIF tag
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
