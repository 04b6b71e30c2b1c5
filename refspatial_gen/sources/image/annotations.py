"""Annotated photo collections -> one in-memory index: images, their object annotations, optional depth/K.

Readers (read_coco.py, read_boxes.py): COCO instances (polygons, compressed and uncompressed RLE), COCO
panoptic (PNG + segments), OpenImages (box CSV, optional mask CSV + mask PNGs) and SUN RGB-D 2D boxes
(folders with image.jpg, depth.png, annotation.json; only the 2D boxes and K are read, never the 3D ground
truth). Masks are materialised per image, lazily, by `annotation_mask` (masks.py), which also validates
that the annotation lies inside the image (else the whole image is dropped: `annotation_out_of_bounds`).
"""

from __future__ import annotations

import os
from functools import lru_cache
from pathlib import Path

from refspatial_gen.core.errors import InputError
from refspatial_gen.sources.image import checks as C
from refspatial_gen.sources.image.masks import BOUNDS_TOLERANCE_PX, annotation_mask, read_panoptic_ids, resolved_bbox
from refspatial_gen.sources.image.read_boxes import read_openimages, read_sunrgbd
from refspatial_gen.sources.image.read_coco import is_coco, is_panoptic, read_coco, read_coco_panoptic
from refspatial_gen.sources.image.records import (
    IMAGE_EXTS,
    Annotation,
    Collection,
    ImageRecord,
    csv_head,
    json_files,
    peek_json,
)

__all__ = [
    "BOUNDS_TOLERANCE_PX",
    "FORMATS",
    "GROUND_STUFF_PREFIXES",
    "IMAGE_EXTS",
    "READERS",
    "SUPPORT_STUFF_PREFIXES",
    "Annotation",
    "Collection",
    "ImageRecord",
    "annotation_mask",
    "detect_format",
    "list_image_files",
    "load_collection",
    "read_coco",
    "read_coco_panoptic",
    "read_openimages",
    "read_panoptic_ids",
    "read_sunrgbd",
    "resolved_bbox",
]

FORMATS = ("auto", "coco", "coco_panoptic", "openimages", "sunrgbd")


# COCO panoptic "stuff" classes that are ground (objects standing there meet the ground plane) or supports
GROUND_STUFF_PREFIXES = (
    "floor",
    "road",
    "pavement",
    "grass",
    "dirt",
    "sand",
    "playingfield",
    "snow",
    "gravel",
    "rug",
    "platform",
    "railroad",
)

SUPPORT_STUFF_PREFIXES = ("table", "counter", "shelf", "desk")


def detect_format(root: Path) -> str:
    """Guess the annotation format of a folder (explicit `format:` in the recipe skips this)."""
    if not root.is_dir():
        raise InputError(str(root), "input folder does not exist" if not root.exists() else "input is not a folder")
    subdirs = sorted(p for p in root.iterdir() if p.is_dir())
    if any((d / "annotation.json").is_file() and (d / "image.jpg").is_file() for d in subdirs):
        return "sunrgbd"
    for p in sorted(root.glob("*.csv")):
        head = csv_head(p)
        if "XMin" in head or "BoxXMin" in head:
            return "openimages"
    found = None
    for p in json_files(root):
        d = peek_json(p)
        if is_panoptic(d):
            return "coco_panoptic"
        if is_coco(d):
            found = "coco"
    if found:
        return found
    for p in json_files(root):  # nothing recognised: a broken JSON file is the likely reason, say which
        if peek_json(p) is None:
            C.load_json_file(p)  # raises InputError with the parse error
    raise InputError(str(root), "no COCO / COCO panoptic / OpenImages / SUN RGB-D annotations found")


READERS = {
    "coco": read_coco,
    "coco_panoptic": read_coco_panoptic,
    "openimages": read_openimages,
    "sunrgbd": read_sunrgbd,
}


def _mtime_key(root: Path) -> tuple:
    return tuple(sorted((p.name, p.stat().st_mtime_ns) for p in root.iterdir() if p.is_file()))


@lru_cache(maxsize=8)
def _load_cached(root: str, fmt: str, annotations: str | None, images_dir: str | None, stamp: tuple) -> Collection:
    return READERS[fmt](Path(root), annotations, images_dir)


def load_collection(
    root: str | Path, fmt: str = "auto", annotations: str | None = None, images_dir: str | None = None
) -> Collection:
    """Read (once per process; cached on the folder's file mtimes) an annotated collection."""
    root = Path(root).resolve()
    if fmt == "auto":
        fmt = detect_format(root)
    if fmt not in READERS:
        raise ValueError(f"unknown annotation format {fmt!r} (known: {', '.join(sorted(READERS))})")
    return _load_cached(str(root), fmt, annotations, images_dir, _mtime_key(root))


def list_image_files(root: Path) -> list[Path]:
    return sorted(p for p in root.iterdir() if p.suffix.lower() in IMAGE_EXTS and os.path.isfile(p))
