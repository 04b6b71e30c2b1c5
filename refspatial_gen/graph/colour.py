"""Basic colour words from an object's own pixels, robust to shading.

Why: a phrase like "the red cup" must describe what the image shows, not what an asset file claims.
Hue is unchanged by shading (a darker red is still red), so chromatic pixels are binned by hue; pixels
with little saturation are achromatic and named by their brightest values (a lit white face stays white
even if other faces are in shadow). Orange with low brightness is brown.

Decision on source colours: the pixel-derived word wins. A source's `attributes["color"]` is used only
when the pixels are inconclusive (no bin holds half the pixels) and at least a quarter of the pixels fall
in that colour's bin; otherwise the object gets no colour word.
"""

from __future__ import annotations

import numpy as np

VOCABULARY = ("red", "orange", "yellow", "green", "blue", "purple", "pink", "brown", "white", "gray", "black")
MIN_PIXELS = 20
MAJORITY = 0.5
SOURCE_SUPPORT = 0.25
# OpenCV hue (0..180) upper bounds of each chromatic bin
_HUE_BINS = (
    (8, "red"),
    (20, "orange"),
    (35, "yellow"),
    (85, "green"),
    (130, "blue"),
    (150, "purple"),
    (170, "pink"),
    (181, "red"),
)
_IDX = {w: k for k, w in enumerate(VOCABULARY)}
_HUE_CODES = np.array([_IDX[w] for _, w in _HUE_BINS], dtype=np.int32)
MAX_PIXELS = 4000
_SAT_MIN = 60  # of 255: below this a pixel is achromatic
_VAL_MIN = 45  # of 255: below this a pixel is black whatever its hue
_ALIASES = {"grey": "gray", "violet": "purple", "magenta": "pink", "cyan": "blue", "beige": "brown", "tan": "brown"}


def hsv_image(rgb: np.ndarray) -> np.ndarray:
    import cv2

    return cv2.cvtColor(np.ascontiguousarray(rgb), cv2.COLOR_RGB2HSV)


def colour_shares(hsv_pixels: np.ndarray) -> dict[str, float]:
    """Share of pixels per colour word for an (N, 3) array of OpenCV HSV pixels."""
    if len(hsv_pixels) > MAX_PIXELS:  # deterministic subsample: shares change by well under 1%
        hsv_pixels = hsv_pixels[:: int(np.ceil(len(hsv_pixels) / MAX_PIXELS))]
    h, s, v = (hsv_pixels[:, k].astype(np.int32) for k in range(3))
    n = len(h)
    code = np.full(n, -1, dtype=np.int32)  # index into VOCABULARY
    chrom = (s >= _SAT_MIN) & (v >= _VAL_MIN)
    bins = np.digitize(h, [b for b, _ in _HUE_BINS[:-1]], right=False)
    code[chrom] = _HUE_CODES[bins[chrom]]
    # orange/yellow hues that are dark overall read as brown; so do dull, dark reds (wood, leather)
    warm = chrom & ((code == _IDX["orange"]) | (code == _IDX["yellow"]))
    if warm.any() and np.percentile(v[warm], 90) < 140:
        code[warm] = _IDX["brown"]
    code[chrom & (code == _IDX["red"]) & (s < 150) & (v < 170)] = _IDX["brown"]
    ach = ~chrom
    if ach.any():
        v90 = np.percentile(v[ach], 90)
        code[ach] = _IDX["white"] if v90 >= 170 else (_IDX["black"] if v90 < 70 else _IDX["gray"])
    counts = np.bincount(code, minlength=len(VOCABULARY))
    return {w: int(counts[k]) / n for k, w in enumerate(VOCABULARY) if counts[k]}


def colour_word(hsv_pixels: np.ndarray, given: str | None = None) -> tuple[str | None, str]:
    """(word or None, how it was decided: "pixels" | "source" | "inconclusive" | "too_few_pixels")."""
    if len(hsv_pixels) < MIN_PIXELS:
        return None, "too_few_pixels"
    shares = colour_shares(hsv_pixels)
    best = max(sorted(shares), key=lambda w: shares[w])
    if shares[best] >= MAJORITY:
        return best, "pixels"
    g = _ALIASES.get((given or "").lower(), (given or "").lower())
    if g in VOCABULARY and shares.get(g, 0.0) >= SOURCE_SUPPORT:
        return g, "source"
    return None, "inconclusive"


def mask_hsv(hsv: np.ndarray, mask: np.ndarray) -> np.ndarray:
    """HSV pixels of the mask's interior (eroded by one pixel when enough remain, to skip edges)."""
    import cv2

    inner = cv2.erode(mask.astype(np.uint8), np.ones((3, 3), np.uint8)).astype(bool)
    m = inner if inner.sum() >= MIN_PIXELS else mask
    return hsv[m]


def mask_hsv_from_rgb(rgb: np.ndarray, mask: np.ndarray) -> np.ndarray:
    """`mask_hsv(hsv_image(rgb), mask)` thinned as `colour_shares` thins it, converting only the pixels
    kept. Why: the HSV conversion is per pixel, so converting the few thousand pixels used instead of the
    whole image gives the same shares for a fraction of the work."""
    import cv2

    pix = mask_hsv(rgb, mask)
    if len(pix) > MAX_PIXELS:
        pix = pix[:: int(np.ceil(len(pix) / MAX_PIXELS))]
    if not len(pix):
        return np.zeros((0, 3), np.uint8)
    return cv2.cvtColor(np.ascontiguousarray(pix[None]), cv2.COLOR_RGB2HSV)[0]
