"""Compact binary encodings for the large arrays, and the JSON envelope with a schema version."""

from __future__ import annotations

import json
from typing import TYPE_CHECKING, Any

import numpy as np
import zstandard

from refspatial_gen import SCHEMA_VERSION

if TYPE_CHECKING:
    from refspatial_gen.core.model import Frame


def dumps(obj: Any) -> bytes:
    """Canonical JSON bytes: sorted keys, no whitespace, so identical data gives identical bytes."""
    return json.dumps(obj, sort_keys=True, separators=(",", ":"), ensure_ascii=False, allow_nan=False).encode("utf-8")


def as_stored(frame: Frame) -> Frame:
    """The frame exactly as a shard stores it: metadata through the canonical JSON (boxes, camera and
    fronts rounded as `to_json` rounds them), depth as little-endian float32. Why: `verify` re-evaluates
    every relation on the stored frame, so graphs and QA pairs must be built on the same numbers; a value
    within rounding of a margin otherwise decides one way in the generator and the other way in verify."""
    from refspatial_gen.core.model import Frame

    depth = np.ascontiguousarray(frame.depth, dtype="<f4")
    return Frame.from_meta_json(json.loads(dumps(frame.meta_json())), frame.rgb, depth)


def envelope(kind: str, payload: dict[str, Any]) -> dict[str, Any]:
    return {"schema_version": SCHEMA_VERSION, "kind": kind, **payload}


def check_envelope(d: dict[str, Any], kind: str) -> dict[str, Any]:
    v = d.get("schema_version")
    if v != SCHEMA_VERSION:
        raise ValueError(f"{kind}: schema_version {v!r} not supported (this code reads {SCHEMA_VERSION})")
    if d.get("kind") != kind:
        raise ValueError(f"expected a {kind!r} record, got {d.get('kind')!r}")
    return d


def encode_depth(depth: np.ndarray, level: int = 3) -> bytes:
    """float32 metres -> zstd-compressed little-endian bytes (lossless)."""
    arr = np.ascontiguousarray(depth, dtype="<f4")
    return zstandard.ZstdCompressor(level=level).compress(arr.tobytes())


def decode_depth(blob: bytes, height: int, width: int) -> np.ndarray:
    raw = zstandard.ZstdDecompressor().decompress(blob, max_output_size=height * width * 4)
    return np.frombuffer(raw, dtype="<f4").reshape(height, width).copy()


def encode_png(rgb: np.ndarray) -> bytes:
    """uint8 RGB -> PNG bytes (lossless, deterministic)."""
    import cv2

    ok, buf = cv2.imencode(".png", np.ascontiguousarray(rgb[..., ::-1]), [cv2.IMWRITE_PNG_COMPRESSION, 3])
    if not ok:
        raise ValueError("PNG encoding failed")
    return buf.tobytes()


def encode_jpeg(rgb: np.ndarray, quality: int = 92) -> bytes:
    import cv2

    ok, buf = cv2.imencode(".jpg", np.ascontiguousarray(rgb[..., ::-1]), [cv2.IMWRITE_JPEG_QUALITY, quality])
    if not ok:
        raise ValueError("JPEG encoding failed")
    return buf.tobytes()


def decode_image(blob: bytes) -> np.ndarray:
    """PNG/JPEG bytes -> uint8 RGB on the stored pixel grid. Raises ValueError on undecodable input.

    Why the grid as stored: depth maps, intrinsics and annotations refer to it, and OpenCV would otherwise
    turn an image carrying an EXIF orientation tag away from them."""
    import cv2

    img = cv2.imdecode(np.frombuffer(blob, dtype=np.uint8), cv2.IMREAD_COLOR | cv2.IMREAD_IGNORE_ORIENTATION)
    if img is None:
        raise ValueError("image bytes could not be decoded")
    return np.ascontiguousarray(img[..., ::-1])
