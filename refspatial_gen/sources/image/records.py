"""An annotated photo collection in memory (images, their annotations, optional depth and K), and the
file helpers every annotation reader shares (annotations.py detects the format and picks the reader)."""

from __future__ import annotations

import json
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from refspatial_gen.sources.image import checks as C

IMAGE_EXTS = (".jpg", ".jpeg", ".png", ".bmp", ".webp")


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


def json_files(root: Path) -> list[Path]:
    return sorted(p for p in root.iterdir() if p.suffix == ".json" and p.is_file())


def peek_json(path: Path) -> dict | list | None:
    try:
        with open(path, encoding="utf-8") as f:
            return json.load(f)
    except (OSError, ValueError, RecursionError):  # ValueError covers JSONDecodeError and UnicodeDecodeError
        return None


def csv_head(p: Path) -> str:
    try:
        with open(p, encoding="utf-8") as f:
            return f.readline()
    except (OSError, UnicodeDecodeError):
        return ""


def find_images_dir(root: Path, hint: str | None) -> Path:
    if hint:
        return root / hint
    for name in ("images", "input_images", "train2017", "val2017", "image"):
        if (root / name).is_dir():
            return root / name
    return root


def mark_invalid(images: dict[str, ImageRecord], iid: str, img_dir: Path, bad: C.Bad) -> None:
    """Mark an image's record invalid (created when the entry itself was unusable); the first problem wins."""
    rec = images.get(iid)
    if rec is None:
        rec = images[iid] = ImageRecord(iid, img_dir / "(invalid)", None, None, [])
    rec.meta.setdefault("invalid", (bad.reason, bad.detail))
