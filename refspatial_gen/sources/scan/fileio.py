"""Image and depth decoding with explicit unit conventions; unreadable input becomes DropUnit."""

from __future__ import annotations

from pathlib import Path

import numpy as np

from refspatial_gen.core.errors import DropUnit

DEPTH_ENCODINGS = ("mm", "tum5000", "sun_shift", "float_m")


def read_rgb(path: str | Path) -> np.ndarray:
    """Any image file -> uint8 RGB HxWx3 (stored pixel grid); a missing or undecodable file drops the frame."""
    from refspatial_gen.core.serialize import decode_image

    p = Path(path)
    if not p.is_file():
        raise DropUnit("image_missing", str(p))
    try:
        blob = p.read_bytes()
        if not blob:
            raise DropUnit("image_unreadable", f"{p}: empty file")
        return decode_image(blob)
    except ValueError as e:
        raise DropUnit("image_unreadable", str(p)) from e
    except OSError as e:
        raise DropUnit("image_unreadable", f"{p}: {e.strerror or e}") from e


def decode_depth_array(raw: np.ndarray, encoding: str) -> np.ndarray:
    """Raw depth values -> float32 metres (0 = unknown). SUN RGB-D raw PNGs store mm with a 3-bit circular shift."""
    if encoding == "mm":
        d = raw.astype(np.float32) / 1000.0
    elif encoding == "tum5000":
        d = raw.astype(np.float32) / 5000.0
    elif encoding == "sun_shift":
        r = raw.astype(np.uint32)
        d = (((r >> 3) | (r << 13)) & 0xFFFF).astype(np.float32) / 1000.0
    elif encoding == "float_m":
        d = raw.astype(np.float32)
    else:
        raise ValueError(f"unknown depth encoding {encoding!r} (known: {', '.join(DEPTH_ENCODINGS)})")
    return d


def read_depth(path: str | Path, encoding: str = "mm") -> np.ndarray:
    """A depth file (16-bit PNG in the given encoding, or .npy metres) -> float32 metres.

    NaN or an all-zero map is NOT rejected here: `checks.check_depth` does that with its own reason codes.
    """
    import cv2

    p = Path(path)
    if not p.is_file():
        raise DropUnit("depth_missing", str(p))
    if p.suffix == ".npy":
        try:
            arr = np.load(p, allow_pickle=False)
        except (ValueError, EOFError, OSError) as e:  # truncated, pickled or not an .npy at all
            raise DropUnit("depth_unreadable", f"{p}: {type(e).__name__}") from e
        if not isinstance(arr, np.ndarray) or arr.ndim != 2 or arr.dtype.kind not in "fiu":
            raise DropUnit("depth_unreadable", f"{p}: expected a 2-D numeric array")
        return np.asarray(arr, dtype=np.float32)
    try:
        buf = np.fromfile(str(p), dtype=np.uint8)
        if buf.size == 0:
            raise DropUnit("depth_unreadable", f"{p}: empty file")
        raw = cv2.imdecode(buf, cv2.IMREAD_UNCHANGED)
    except (OSError, cv2.error) as e:
        raise DropUnit("depth_unreadable", f"{p}: {type(e).__name__}") from e
    if raw is None or raw.ndim != 2:
        raise DropUnit("depth_unreadable", str(p))
    if raw.dtype != np.uint16 and encoding != "float_m":
        raise DropUnit("depth_unreadable", f"{p}: expected 16-bit depth, got {raw.dtype}")
    return decode_depth_array(raw, encoding)
