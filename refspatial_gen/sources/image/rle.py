"""COCO mask encodings: compressed RLE strings, uncompressed RLE and polygons -> boolean masks.

Why our own: pycocotools is a C extension that does not always build; the compressed-RLE codec is a
few lines (a port of `rleFrString`/`rleToString` from COCO's maskApi.c) and the polygon rasteriser is
cv2.fillPoly at 1/16-pixel precision.
"""

from __future__ import annotations

import numpy as np

from refspatial_gen.core.mask import RLE


def decode_counts_string(s: str | bytes) -> list[int]:
    """COCO compressed RLE string -> run lengths (column-major, starting with background)."""
    if isinstance(s, bytes):
        s = s.decode("ascii")
    counts: list[int] = []
    p = 0
    n = len(s)
    while p < n:
        x = 0
        k = 0
        more = True
        while more:
            if p >= n:
                raise ValueError("truncated compressed RLE string")
            c = ord(s[p]) - 48
            x |= (c & 0x1F) << (5 * k)
            more = bool(c & 0x20)
            p += 1
            k += 1
            if not more and (c & 0x10):
                x |= -1 << (5 * k)
        if len(counts) > 2:
            x += counts[-2]
        counts.append(x)
    return counts


def encode_counts_string(counts: list[int] | tuple[int, ...]) -> str:
    """Run lengths -> COCO compressed RLE string (inverse of `decode_counts_string`)."""
    out: list[str] = []
    for i, x in enumerate(counts):
        x = int(x)
        if i > 2:
            x -= int(counts[i - 2])
        more = True
        while more:
            c = x & 0x1F
            x >>= 5
            more = (x != -1) if (c & 0x10) else (x != 0)
            if more:
                c |= 0x20
            out.append(chr(c + 48))
    return "".join(out)


def rle_from_coco(seg: dict, height: int, width: int) -> RLE:
    """A COCO RLE dict ({"size": [h, w], "counts": str | list}) -> core RLE, checking its size."""
    size = seg.get("size")
    if size is None or [int(size[0]), int(size[1])] != [height, width]:
        raise ValueError(f"RLE size {size} does not match the image ({height}, {width})")
    counts = seg["counts"]
    runs = decode_counts_string(counts) if isinstance(counts, (str, bytes)) else [int(c) for c in counts]
    if any(r < 0 for r in runs):
        raise ValueError("RLE has a negative run")
    if sum(runs) != height * width:
        raise ValueError(f"RLE runs sum to {sum(runs)}, expected {height * width}")
    return RLE(height, width, tuple(runs))


def polygons_to_mask(polygons: list[list[float]], height: int, width: int) -> np.ndarray:
    """COCO polygons (x, y in continuous pixel coordinates, pixel i spans [i, i+1)) -> bool mask.

    A pixel is in the mask when its centre is inside the polygon (cv2.fillPoly on centre coordinates,
    at 1/16-pixel precision)."""
    import cv2

    m = np.zeros((height, width), np.uint8)
    pts = []
    for poly in polygons:
        a = np.asarray(poly, dtype=np.float64).reshape(-1, 2)
        if len(a) < 3:
            continue
        pts.append(np.round((a - 0.5) * 16.0).astype(np.int32))
    if pts:
        cv2.fillPoly(m, pts, 1, lineType=cv2.LINE_8, shift=4)
    return m.astype(bool)


def polygons_extent(polygons: list[list[float]]) -> tuple[float, float, float, float]:
    """(x0, y0, x1, y1) of all polygon vertices."""
    a = np.concatenate([np.asarray(p, dtype=np.float64).reshape(-1, 2) for p in polygons if len(p) >= 2])
    return float(a[:, 0].min()), float(a[:, 1].min()), float(a[:, 0].max()), float(a[:, 1].max())


def box_mask(bbox: tuple[float, float, float, float], height: int, width: int) -> np.ndarray:
    """Pixels whose centre lies inside the box (x0, y0, x1, y1), continuous coordinates."""
    x0, y0, x1, y1 = bbox
    m = np.zeros((height, width), bool)
    c0, c1 = int(np.ceil(x0 - 0.5)), int(np.ceil(x1 - 0.5))
    r0, r1 = int(np.ceil(y0 - 0.5)), int(np.ceil(y1 - 0.5))
    m[max(r0, 0) : max(min(r1, height), 0), max(c0, 0) : max(min(c1, width), 0)] = True
    return m
