"""verify's own re-check of the contrast floor (the generator's rule: graph/contrast.py).

Why its own code: a named object must be one a person can make out against its surroundings (issue #15,
audit round 4: a near-black toy block, a black phone on black wood, a featureless black chair slab). verify
recomputes, from the stored image and mask alone and sharing no code with the graph: CIELAB by the CIE
formulas (sRGB D65, not OpenCV), the object's interior and the ring around it by an exact Euclidean
distance transform (scipy, not OpenCV's disc dilation), the medians and the L* spread. A pair fails only
when the object is below the recorded floor (graph.meta["truth_floor"]) by more than the tolerances below,
so the two implementations' rounding never decides a borderline object. Floors recorded before this rule
(no `dark_lightness` key) check nothing.
"""

from __future__ import annotations

from typing import Any

import numpy as np

ERODE, GAP, RING = 2.0, 2.0, 8.0  # px at 640x480: interior deeper than 2 px; ring 2..8 px outside
DE_TOL, L_TOL, DETAIL_TOL = 1.0, 1.0, 0.5  # CIE76, L*, L* spread: the two implementations differ by less
_M = np.array([[0.4124564, 0.3575761, 0.1804375], [0.2126729, 0.7151522, 0.0721750], [0.0193339, 0.1191920, 0.9503041]])
_WHITE = np.array([0.95047, 1.0, 1.08883])


def lab(rgb: np.ndarray) -> np.ndarray:
    """(N, 3) uint8 sRGB -> (N, 3) CIELAB (D65), by the CIE formulas."""
    c = np.asarray(rgb, np.float64) / 255.0
    lin = np.where(c <= 0.04045, c / 12.92, ((c + 0.055) / 1.055) ** 2.4)
    t = (lin @ _M.T) / _WHITE
    e = 216.0 / 24389.0
    f = np.where(t > e, np.cbrt(t), (24389.0 / 27.0 * t + 16.0) / 116.0)
    return np.stack([116.0 * f[:, 1] - 16.0, 500.0 * (f[:, 0] - f[:, 1]), 200.0 * (f[:, 1] - f[:, 2])], axis=1)


def _measure(rgb: np.ndarray, mask: np.ndarray, scale: float) -> tuple[float, float, float] | None:
    """(contrast, lightness, detail) of the object, or None when it has no pixels or no ring in the image."""
    from scipy.ndimage import distance_transform_edt

    ys, xs = np.nonzero(mask)
    if not len(xs):
        return None
    pad = int(np.ceil(RING * scale)) + 2  # the ring lies within this of the mask: the rest is never read
    y0, x0 = max(0, ys.min() - pad), max(0, xs.min() - pad)
    mask, rgb = (
        mask[y0 : ys.max() + pad + 1, x0 : xs.max() + pad + 1],
        rgb[y0 : ys.max() + pad + 1, x0 : xs.max() + pad + 1],
    )
    inside = distance_transform_edt(np.pad(mask, 1))[1:-1, 1:-1]  # distance to the nearest outside pixel
    outside = distance_transform_edt(~mask)  # distance to the nearest object pixel
    inner = inside > max(1.0, round(ERODE * scale))
    if inner.sum() < 12:
        inner = mask
    gap = max(1.0, round(GAP * scale))
    ring = (outside > gap) & (outside <= gap + max(1.0, round((RING - GAP) * scale)))
    if not ring.any():
        return None
    obj, around = lab(rgb[inner]), lab(rgb[ring])
    med = np.median(obj, axis=0)
    lo, hi = np.percentile(obj[:, 0], [10, 90])
    return float(np.linalg.norm(med - np.median(around, axis=0))), float(med[0]), float(hi - lo)


def low_contrast(frame: Any, o: Any, floor: dict[str, Any]) -> str | None:
    """Why the object cannot be made out (clearly below the recorded contrast floor), or None."""
    if "dark_lightness" not in floor or o.mask is None:
        return None
    mask = o.mask.decode().astype(bool)
    scale = float(np.sqrt(frame.camera.width * frame.camera.height / 307200.0))
    m = _measure(np.asarray(frame.rgb), mask, scale)
    if m is None:
        return None
    de, light, detail = m
    need_de = float(floor.get("min_contrast_delta_e", 0.0))
    if de < need_de - DE_TOL:
        return f"contrast with its surroundings {de:.1f} < {need_de} (CIE76)"
    if light >= float(floor["dark_lightness"]) - L_TOL:
        return None
    px, need_px = int(mask.sum()), float(floor.get("min_dark_px", 0.0)) * scale * scale
    if px < need_px:
        return f"dark (L* {light:.1f}) and small: {px} visible pixels < {need_px:.0f}"
    flat, silhouette = float(floor.get("min_dark_detail", 0.0)), float(floor.get("dark_silhouette_delta_e", 0.0))
    if detail < flat - DETAIL_TOL and de < silhouette - DE_TOL:
        return f"dark (L* {light:.1f}) and flat: L* spread {detail:.1f} < {flat}, contrast {de:.1f} < {silhouette}"
    return None
