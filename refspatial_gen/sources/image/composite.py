"""Composite photos (collages, diptychs): several photos pasted into one image share no 3D space, so a
depth order, a distance or "left of" across the panels is meaningless (audit round 2, COCO 79841: two street
photos side by side, "the thinnest bike" compared a bike of each).

The cue: a separator band. Collages are pasted with a uniform strip between the panels (black, white) that
runs the full height (or width) of the image; in a photo nothing stays one colour over the whole height:
door frames and wall edges make full-height *edges* (COCO 540186: a door frame edge on 97% of the rows) but
their colour changes with the light. Measured on the 52 shared COCO photos: the collage's band has a
per-column colour spread of 1.4 (max channel standard deviation over the full height, 0..255); the
smallest of every other photo's interior columns or rows is 6.8. Default threshold 3.0.
"""

from __future__ import annotations

import numpy as np

from refspatial_gen.core.errors import DropUnit

INTERIOR = 0.1  # a band must lie this share of the length away from both image edges (letterboxes are not seams)
MIN_BAND = 2  # columns (rows) of a band
MAX_BAND = 0.1  # a band is a strip between panels: at most this share of the length wide
STEP = 30.0  # the panels beside the band: a colour step above this (0..255, any channel) ...
SEAM_SHARE = 0.5  # ... along at least this share of the band's length, on both sides
EDGE = 3  # within this many columns (rows) of the band (JPEG blurs the step over a pixel or two)


def raise_if_composite(rgb: np.ndarray, max_std: float, name: str) -> None:
    """DropUnit("image_composite") when the photo is pasted from several (`max_std` 0: never)."""
    band = separator_band(rgb, max_std) if max_std > 0 else None
    if band is not None:
        raise DropUnit("image_composite", f"{name}: uniform separator {band[0]}s {band[1]}-{band[2]}")


def separator_band(rgb: np.ndarray, max_std: float) -> tuple[str, int, int] | None:
    """(axis "column"|"row", first, last index) of a uniform band splitting the image into panels, or None.

    A band: MIN_BAND to MAX_BAND x the length adjacent interior columns (rows), each one colour over the whole
    height (width): every channel's standard deviation along it is below `max_std`; and a seam on both sides:
    a column (row) within EDGE of it differs from the band's colour by more than STEP along SEAM_SHARE of its
    length (a flat background strip of a rendered scene runs into more flat background, not into a photo)."""
    a = np.asarray(rgb, np.float32)
    for name, img in (("column", a), ("row", a.transpose(1, 0, 2))):
        n = img.shape[1]
        spread = img.std(axis=0).max(axis=1)  # (n,) per column: the largest channel spread over the height
        lo, hi = int(np.ceil(INTERIOR * n)), int(np.floor((1 - INTERIOR) * n))
        flat = np.zeros(n, bool)
        flat[lo:hi] = spread[lo:hi] < max_std
        for first, last in _runs(flat, MIN_BAND, max(MIN_BAND, int(MAX_BAND * n))):
            colour = img[:, first : last + 1].mean(axis=(0, 1))
            if all(_seam(img, cols, colour) for cols in (range(first - EDGE, first), range(last + 1, last + 1 + EDGE))):
                return name, first, last
    return None


def _seam(img: np.ndarray, cols: range, colour: np.ndarray) -> bool:
    return any(float((np.abs(img[:, c] - colour).max(axis=1) > STEP).mean()) >= SEAM_SHARE for c in cols)


def _runs(flags: np.ndarray, min_len: int, max_len: int) -> list[tuple[int, int]]:
    """(first, last) of every run of True of length min_len..max_len."""
    out = []
    start = None
    for i, f in enumerate([*flags.tolist(), False]):
        if f and start is None:
            start = i
        elif not f and start is not None:
            if min_len <= i - start <= max_len:
                out.append((start, i - 1))
            start = None
    return out
