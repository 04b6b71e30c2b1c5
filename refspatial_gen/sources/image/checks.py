"""Validation of annotation files: top-level problems stop planning, entry-level ones drop one image.

Why here: annotation readers must never let a malformed value reach the geometry (a string bbox, a
`width: "wide"`, a NaN polygon) and fail there with a traceback. Two kinds of problem:

  * the file itself is unusable (not JSON, truncated, `images` not a list): `InputError(path, message)`,
    the run stops before any work (exit 2) — nothing can be planned from it;
  * one entry is malformed: `Bad(reason, detail)` is raised by the value checks below; the reader records
    it on the image's record (`ImageRecord.meta["invalid"]`), and loading that image raises
    `DropUnit(reason, detail)`, counted in the run report. The other images are unaffected.
"""

from __future__ import annotations

import math
from pathlib import Path, PurePosixPath
from typing import Any

from refspatial_gen.core.errors import DropUnit, InputError
from refspatial_gen.core.jsonfile import loads_checked

MAX_JSON_BYTES = 2 * 1024**3  # a COCO train2017 instances file is ~450 MB


class Bad(Exception):
    """One malformed entry: becomes the image's drop reason."""

    def __init__(self, reason: str, detail: str) -> None:
        super().__init__(f"{reason}: {detail}")
        self.reason, self.detail = reason, detail


def load_json_file(path: Path) -> Any:
    """A top-level annotation file, strictly: every problem is an InputError naming the file."""
    try:
        size = path.stat().st_size
        if size == 0:
            raise InputError(str(path), "annotation file is empty")
        if size > MAX_JSON_BYTES:
            raise InputError(str(path), f"annotation file is {size} bytes (limit {MAX_JSON_BYTES})")
        with open(path, "rb") as f:
            raw = f.read()
    except OSError as e:
        raise InputError(str(path), f"cannot read: {e.strerror or e}") from None
    return loads_checked(raw, path)


def require_list(data: dict, key: str, path: Path, required: bool = True) -> list:
    v = data.get(key)
    if v is None and not required:
        return []
    if not isinstance(v, list):
        raise InputError(str(path), f"`{key}` must be a list, got {type(v).__name__}")
    return v


def finite(v: Any, what: str) -> float:
    if isinstance(v, bool) or not isinstance(v, (int, float)) or not math.isfinite(v):
        raise Bad("annotation_invalid", f"{what} must be a finite number, got {_short(v)}")
    return float(v)


def positive_int(v: Any, what: str) -> int:
    """An image dimension: a positive integer (640 or 640.0), never a string or a bool."""
    if (
        isinstance(v, bool)
        or not isinstance(v, (int, float))
        or not math.isfinite(v)
        or v != int(v)
        or v <= 0
        or v > 1_000_000
    ):
        raise Bad("annotation_invalid", f"{what} must be a positive integer, got {_short(v)}")
    return int(v)


def int_id(v: Any, what: str) -> int:
    if isinstance(v, bool) or not isinstance(v, int):
        raise Bad("annotation_invalid", f"{what} must be an integer, got {_short(v)}")
    return v


def entry_id(v: Any) -> str | None:
    """An image id as a unit key part: an int or a non-empty plain string."""
    if isinstance(v, bool):
        return None
    if isinstance(v, int):
        return str(v)
    if isinstance(v, str) and v and len(v) <= 200 and v.isprintable():
        return v
    return None


def bbox_xywh(v: Any, what: str = "bbox") -> tuple[float, float, float, float]:
    """COCO [x, y, w, h] -> (x0, y0, x1, y1); four finite numbers, w and h >= 0."""
    if not isinstance(v, (list, tuple)) or len(v) != 4:
        raise Bad("annotation_invalid", f"{what} must be [x, y, width, height], got {_short(v)}")
    x, y, w, h = (finite(c, what) for c in v)
    if w < 0 or h < 0:
        raise Bad("annotation_invalid", f"{what} has a negative size {w} x {h}")
    return x, y, x + w, y + h


def polygons(v: Any) -> list[list[float]]:
    """COCO polygons: lists of >= 3 finite (x, y) pairs."""
    out = []
    for k, poly in enumerate(v):
        if not isinstance(poly, list) or len(poly) < 6 or len(poly) % 2:
            raise Bad("annotation_invalid", f"segmentation polygon {k} must list >= 3 x, y pairs")
        out.append([finite(c, f"segmentation polygon {k}") for c in poly])
    return out


def rle(v: dict) -> dict:
    """COCO RLE {"size": [h, w], "counts": str | [ints >= 0]}; its size is checked against the image later."""
    size, counts = v.get("size"), v.get("counts")
    if (
        not isinstance(size, list)
        or len(size) != 2
        or not all(isinstance(s, int) and not isinstance(s, bool) and s > 0 for s in size)
    ):
        raise Bad("annotation_invalid", f"segmentation RLE size must be [height, width], got {_short(size)}")
    if isinstance(counts, str):
        if not counts.isascii():
            raise Bad("annotation_invalid", "segmentation RLE counts string is not ASCII")
    elif not isinstance(counts, list) or not all(
        isinstance(c, int) and not isinstance(c, bool) and c >= 0 for c in counts
    ):
        raise Bad("annotation_invalid", "segmentation RLE counts must be a string or a list of integers >= 0")
    return v


def segmentation(v: Any) -> tuple[str, Any]:
    """-> (kind, payload): "polygon" | "rle" | "box" (no segmentation)."""
    if v is None or v == []:
        return "box", None
    if isinstance(v, list):
        return "polygon", polygons(v)
    if isinstance(v, dict):
        return "rle", rle(v)
    raise Bad("annotation_invalid", f"segmentation must be polygons or an RLE mapping, got {type(v).__name__}")


def flag(v: Any, what: str) -> bool:
    if v is None:
        return False
    if isinstance(v, bool) or (isinstance(v, int) and v in (0, 1)):
        return bool(v)
    raise Bad("annotation_invalid", f"{what} must be 0 or 1, got {_short(v)}")


def relative_file(v: Any, base: Path, what: str) -> Path:
    """A file named by the annotations: a relative path that stays inside `base`."""
    if not isinstance(v, str) or not v or "\0" in v:
        raise Bad("annotation_invalid", f"{what} must be a file name, got {_short(v)}")
    p = PurePosixPath(v.replace("\\", "/"))
    if p.is_absolute() or ".." in p.parts:
        raise Bad("path_outside_input", f"{what} {v!r} leaves the input folder")
    return base / p


def raise_if_invalid(meta: dict) -> None:
    """Loading a record marked invalid by its reader: the image is dropped with the recorded reason."""
    bad = meta.get("invalid")
    if bad:
        raise DropUnit(bad[0], bad[1])


def _short(v: Any, limit: int = 40) -> str:
    r = repr(v)
    return r if len(r) <= limit else r[: limit - 3] + "..."
