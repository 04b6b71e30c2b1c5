"""Binary masks as COCO-style uncompressed RLE (column-major runs, starting with background)."""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

import numpy as np


@dataclass(frozen=True)
class RLE:
    height: int
    width: int
    counts: tuple[int, ...]

    @classmethod
    def encode(cls, mask: np.ndarray) -> RLE:
        m = np.asarray(mask, dtype=bool)
        flat = m.ravel(order="F").astype(np.int8)
        if flat.size == 0:
            return cls(m.shape[0], m.shape[1], ())
        change = np.flatnonzero(np.diff(flat)) + 1
        bounds = np.concatenate([[0], change, [flat.size]])
        runs = np.diff(bounds).tolist()
        if flat[0] == 1:
            runs = [0] + runs
        return cls(int(m.shape[0]), int(m.shape[1]), tuple(int(r) for r in runs))

    def decode(self) -> np.ndarray:
        counts = np.asarray(self.counts, dtype=np.int64)
        values = np.zeros(counts.size, dtype=bool)
        values[1::2] = True
        flat = np.repeat(values, counts)
        if flat.size != self.height * self.width:
            raise ValueError(f"RLE counts sum to {flat.size}, expected {self.height * self.width}")
        return flat.reshape((self.height, self.width), order="F")

    @property
    def area(self) -> int:
        return int(sum(self.counts[1::2]))

    def to_json(self) -> dict[str, Any]:
        return {"size": [self.height, self.width], "counts": list(self.counts)}

    @classmethod
    def from_json(cls, d: dict[str, Any]) -> RLE:
        return cls(int(d["size"][0]), int(d["size"][1]), tuple(int(c) for c in d["counts"]))


def answer_pixel(mask: np.ndarray) -> tuple[float, float] | None:
    """RefSpatial's object point: centroid of the largest connected part of the visible mask, moved to the
    nearest mask pixel if the centroid falls outside. Returns (x, y) in pixels, or None for an empty mask."""
    import cv2

    m = np.asarray(mask, dtype=np.uint8)
    if not m.any():
        return None
    n, labels, stats, centroids = cv2.connectedComponentsWithStats(m, connectivity=8)
    best = 1 + int(np.argmax(stats[1:, cv2.CC_STAT_AREA]))
    cx, cy = centroids[best]
    ix, iy = int(round(cx)), int(round(cy))
    part = labels == best
    if 0 <= iy < m.shape[0] and 0 <= ix < m.shape[1] and part[iy, ix]:
        return float(ix), float(iy)
    ys, xs = np.nonzero(part)
    k = int(np.argmin((xs - cx) ** 2 + (ys - cy) ** 2))
    return float(xs[k]), float(ys[k])


def normalise_point(x: float, y: float, width: int, height: int) -> tuple[float, float]:
    """Pixel (x, y) -> RefSpatial normalised point, three decimals, pixel centres."""
    return round((x + 0.5) / width, 3), round((y + 0.5) / height, 3)


def denormalise_point(px: float, py: float, width: int, height: int) -> tuple[int, int]:
    """Normalised point -> the pixel it falls in (clamped to the image)."""
    return min(width - 1, max(0, int(px * width))), min(height - 1, max(0, int(py * height)))
