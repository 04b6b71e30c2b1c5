"""The contrast floor: can a person make the object out against what surrounds it?

Why (issue #15, audit round 4): referents passed the pixel and visible-fraction floors and still could not
be made out: a near-black 14 px toy block and a black phone sliver on a black-wood nightstand, a black chair
rendered as a featureless slab, a black camera that is a plain dark rectangle, a dark-green bowl speck on a
far cabinet. The pixel count says how much of an object is in the picture, not whether it shows.

Measured from the frame's RGB (sRGB, CIELAB D65) and the object's visible mask (pixel lengths for a 640x480
image, scaled like the other floors):
  - `contrast`: CIE76 difference between the object's median colour (its mask eroded by ERODE_PX, so edge
    pixels mixed with the background do not count) and the median colour of a ring RING_PX wide around it
    (starting GAP_PX outside the mask). Both medians are per channel.
  - `lightness`: the object's median L*.
  - `detail`: the spread of L* inside the eroded mask (its 90th minus 10th percentile): shading across
    faces, parts, texture. A flat dark silhouette has next to none.

An object is below the contrast floor (`below_floor_contrast`) when
  - its contrast is under `min_contrast_delta_e` (it melts into its surroundings), or
  - it is dark (lightness under `dark_lightness`) and either small (visible pixels under `min_dark_px`,
    scaled by area: a dark speck) or flat (detail under `min_dark_detail`: no shading, no parts) with a
    silhouette that does not stand out either (contrast under `dark_silhouette_delta_e`): a featureless
    black slab on dark wood. A flat dark-blue mug on a light table still reads by its outline.

Recipe keys (`graph: truth:`, graph/visibility.py; defaults measured in docs/quality.md and docs/sim.md):
  min_contrast_delta_e     4.0   CIE76 object vs ring below which an object melts into its surroundings
  dark_lightness           20.0  median L* below which an object is dark
  min_dark_px              600   visible pixels (at 640x480) a dark object needs
  min_dark_detail          3.0   L* spread (p90 - p10) a dark object needs ...
  dark_silhouette_delta_e  30.0  ... unless its contrast with its surroundings is at least this

Like every floor object it stays in the scene as a distractor and is never named (qa/faint.py); verify
re-checks it from the stored image and masks by its own code (qa/verify_contrast.py)."""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

import numpy as np

CONTRAST = "below_floor_contrast"  # graph.meta["truth"] key, node attribute "below_floor"
ERODE_PX = 2  # inner pixels: the mask minus its outer 2 px (edges blend with the background)
GAP_PX, RING_PX = 2, 6  # the ring: pixels 2..8 px outside the mask
MIN_INNER = 12  # fewer eroded pixels than this: the whole mask is used
CONTRAST_DEFAULTS: dict[str, float] = {
    "min_contrast_delta_e": 4.0,
    "dark_lightness": 20.0,
    "min_dark_px": 600.0,
    "min_dark_detail": 3.0,
    "dark_silhouette_delta_e": 30.0,
}
CONTRAST_DOCS: dict[str, tuple[type, float, str]] = {
    "min_contrast_delta_e": (float, 100.0, "CIE76 object vs its surroundings below which it cannot be made out"),
    "dark_lightness": (float, 100.0, "median L* below which an object is dark (needs min_dark_px, detail)"),
    "min_dark_px": (float, 1_000_000.0, "visible pixels (at 640x480) a dark object needs"),
    "min_dark_detail": (float, 100.0, "L* spread (p90 - p10) inside a dark object below which it is flat"),
    "dark_silhouette_delta_e": (float, 200.0, "a flat dark object still counts when its contrast is this high"),
}


@dataclass(frozen=True)
class Contrast:
    contrast: float  # CIE76 between the median colours of the object and of its ring
    lightness: float  # median L* of the object
    detail: float  # L* 90th - 10th percentile inside the object


def lab_image(rgb: np.ndarray) -> np.ndarray:
    """HxWx3 uint8 sRGB -> HxWx3 float32 CIELAB (L 0..100)."""
    import cv2

    return np.asarray(cv2.cvtColor(np.asarray(rgb, np.float32) / 255.0, cv2.COLOR_RGB2Lab), np.float32)


def _disc(r: int) -> np.ndarray:
    y, x = np.mgrid[-r : r + 1, -r : r + 1]
    return np.asarray(x * x + y * y <= r * r, np.uint8)


def measure(lab: np.ndarray, mask: np.ndarray, scale: float = 1.0) -> Contrast | None:
    """The object's contrast, lightness and detail (None without pixels or without a ring in the image)."""
    import cv2

    rows, cols = np.flatnonzero(mask.any(axis=1)), np.flatnonzero(mask.any(axis=0))
    if not len(rows):
        return None
    erode, gap, ring = (max(1, int(round(v * scale))) for v in (ERODE_PX, GAP_PX, RING_PX))
    pad = gap + ring + 1
    H, W = mask.shape
    y0, y1 = max(0, rows[0] - pad), min(H, rows[-1] + pad + 1)
    x0, x1 = max(0, cols[0] - pad), min(W, cols[-1] + pad + 1)
    m = mask[y0:y1, x0:x1].astype(np.uint8)
    sub = lab[y0:y1, x0:x1]
    inner = cv2.erode(m, _disc(erode), borderType=cv2.BORDER_CONSTANT, borderValue=0).astype(bool)
    if inner.sum() < MIN_INNER:
        inner = m.astype(bool)
    near = cv2.dilate(m, _disc(gap)).astype(bool)
    outer = cv2.dilate(m, _disc(gap + ring)).astype(bool) & ~near
    if not outer.any():
        return None
    obj, around = np.median(sub[inner], axis=0), np.median(sub[outer], axis=0)
    lo, hi = np.percentile(sub[inner][:, 0], [10, 90])
    return Contrast(float(np.linalg.norm(obj - around)), float(obj[0]), float(hi - lo))


def contrast_reason(c: Contrast | None, visible_px: int, floor: Any, scale: float) -> str | None:
    """CONTRAST when the object cannot be made out (the rules of the module docstring), else None."""
    if c is None:
        return None
    if c.contrast < float(floor.min_contrast_delta_e):
        return CONTRAST
    if c.lightness >= float(floor.dark_lightness):
        return None
    if visible_px < float(floor.min_dark_px) * scale * scale:
        return CONTRAST
    if c.detail < float(floor.min_dark_detail) and c.contrast < float(floor.dark_silhouette_delta_e):
        return CONTRAST
    return None


def contrast_reasons(geom: Any, floor: Any, masks: list[np.ndarray | None], why: list[str | None]) -> list[str | None]:
    """`why` (the visibility floor's reasons per object position) with CONTRAST added where an object that
    passed it cannot be made out; the image is converted to CIELAB once, and only when needed."""
    from refspatial_gen.graph.visibility import px_scale

    out = list(why)
    cam = geom.frame.camera
    scale = px_scale(cam.width, cam.height)
    lab: np.ndarray | None = None
    for i, m in enumerate(masks):
        if out[i] is not None or m is None:
            continue
        if lab is None:
            lab = lab_image(geom.frame.rgb)
        out[i] = contrast_reason(measure(lab, m, scale), int(m.sum()), floor, scale)
    return out
