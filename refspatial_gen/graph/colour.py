"""Basic colour words from an object's own pixels: a calibrated namer with a confidence margin.

Why: a phrase like "the red car" must describe what the picture shows. Binning HSV hue named a teal car
"black" and a shaded yellow taxi "brown" (about 1 colour word in 4 was wrong on photos). This namer:

- works in CIELAB (perceptual distances), naming each pixel by its nearest prototype among the XKCD colour
  survey's names of the eleven basic terms ("forest green", "light blue"; `truth/data/colour_names.yaml`,
  with its source); a pixel about as near two terms (teal, olive) names nothing;
- takes shading out first (`unshade`): a taxi's shaded flank is olive, its lit door yellow;
- names a colour only when the winning term holds at least `colour_min_share` of those pixels and beats
  the runner-up (another term or "no basic term") by `colour_margin` (recipe thresholds,
  `graph.constants.Thresholds`); otherwise the object gets no colour word ("margin");
- never names a colour for people or animals (`truth/data/no_colour.yaml`): clothes vary and skin or fur
  colour is not a referring word a person would sign off on.

A source's `attributes["color"]` (the simulator's known colour) is used only when it is also the pixels'
winning term and the margin alone failed ("source").
"""

from __future__ import annotations

from functools import lru_cache
from pathlib import Path

import numpy as np

VOCABULARY = ("red", "orange", "yellow", "green", "blue", "purple", "pink", "brown", "white", "gray", "black")
NONE = ""  # the bucket of pixels nearest a prototype that is no basic term
MIN_PIXELS = 20
MAX_PIXELS = 4000
MIN_SHARE = 0.5  # defaults of Thresholds.colour_min_share / colour_margin
MARGIN = 0.2
LIT_QUANTILE = 0.8
MAX_GAIN = 4.0
WHITE_QUANTILE = 0.99
MAX_EXPOSURE = 3.0  # at most this gain from the picture's white level
HIGHLIGHT_QUANTILE = 0.02
ACHROMATIC_CHROMA, ACHROMATIC_SLOPE = 3.0, 0.08  # CIELAB chroma below 3 + 0.08 L: white, gray or black by lightness
WHITE_L, BLACK_L, L_BAND = 78.0, 22.0, 3.0  # lightness bounds of the achromatic terms, +- an undecided band
LUT_LEVELS = 32  # 5 bits per channel
PIXEL_RATIO = 0.8  # a pixel names a term when its nearest prototype is this much nearer than any other term's
_ALIASES = {"grey": "gray", "violet": "purple", "magenta": "pink", "cyan": "blue", "silver": "gray"}
_DATA = Path(__file__).resolve().parent.parent / "truth" / "data"


def _lab(rgb01: np.ndarray) -> np.ndarray:
    """(N, 3) sRGB in 0..1 -> CIELAB (D65; L 0..100)."""
    import cv2

    a = np.ascontiguousarray(np.asarray(rgb01, np.float32).reshape(1, -1, 3))
    return cv2.cvtColor(a, cv2.COLOR_RGB2Lab)[0].astype(np.float32)


@lru_cache(maxsize=1)
def prototypes() -> tuple[np.ndarray, np.ndarray]:
    """(P, 3) CIELAB prototypes and (P,) codes: index into VOCABULARY, or -1 for no basic term."""
    import yaml

    raw = yaml.load((_DATA / "colour_names.yaml").read_text(), Loader=getattr(yaml, "CSafeLoader", yaml.SafeLoader))
    rgb, codes = [], []
    for hexv, _name, word in raw["prototypes"]:
        h = str(hexv).lstrip("#")
        rgb.append([int(h[k : k + 2], 16) / 255.0 for k in (0, 2, 4)])
        codes.append(VOCABULARY.index(word) if word else -1)
    return _lab(np.array(rgb)), np.array(codes, np.int32)


@lru_cache(maxsize=1)
def _uncoloured() -> frozenset[str]:
    import yaml

    raw = yaml.safe_load((_DATA / "no_colour.yaml").read_text())
    return frozenset(_norm(c) for group in raw["categories"].values() for c in group)


def _norm(category: str) -> str:
    return " ".join(category.lower().replace("_", " ").replace("-", " ").split())


def never_coloured(category: str | None) -> bool:
    """True for people and animals (any name in `no_colour.yaml`, plural 's' and case ignored)."""
    if not category:
        return False
    c = _norm(category)
    names = _uncoloured()
    return c in names or (c.endswith("s") and c[:-1] in names)


@lru_cache(maxsize=1)
def _lut() -> tuple[np.ndarray, np.ndarray]:
    """(code, lightness) of every cell of a 32-level sRGB cube (cell centres), computed once: naming a
    pixel is then one table lookup. A cell's code is the term of its nearest named prototype, or -1 when
    another term's nearest prototype is almost as near (distance ratio above PIXEL_RATIO: between terms)."""
    lv = (np.arange(LUT_LEVELS, dtype=np.float32) + 0.5) / LUT_LEVELS
    cube = np.stack(np.meshgrid(lv, lv, lv, indexing="ij"), axis=-1).reshape(-1, 3)
    lab = _lab(cube)
    P, codes = prototypes()
    keep = np.argsort(codes, kind="stable")[np.sort(codes) >= 0]  # named prototypes, grouped by term
    P, codes = P[keep], codes[keep]
    starts = np.searchsorted(codes, np.arange(len(VOCABULARY)))
    dist = np.empty((len(lab), len(VOCABULARY)), np.float32)
    for k in range(0, len(lab), 4096):  # bounded memory; nearest prototype of each term
        c = lab[k : k + 4096]
        d = ((c[:, None, :] - P[None, :, :]) ** 2).sum(-1)
        dist[k : k + 4096] = np.minimum.reduceat(d, starts, axis=1)
    order = np.argsort(dist, axis=1)
    d1 = np.take_along_axis(dist, order[:, :1], 1)[:, 0]
    d2 = np.take_along_axis(dist, order[:, 1:2], 1)[:, 0]
    code = np.where(d1 <= PIXEL_RATIO**2 * d2, order[:, 0], -1).astype(np.int32)  # squared distances
    # achromatic pixels: named by lightness alone (the survey's monitor patches call near-white "pale grey";
    # in a picture normalised to its white level, people call those white), with a band between terms
    L, chroma = lab[:, 0], np.hypot(lab[:, 1], lab[:, 2])
    ach = chroma < ACHROMATIC_CHROMA + ACHROMATIC_SLOPE * L  # dark colours have little chroma (wood)
    band = ach & ((np.abs(L - WHITE_L) < L_BAND) | (np.abs(L - BLACK_L) < L_BAND))
    code[ach] = np.where(
        L[ach] >= WHITE_L,
        VOCABULARY.index("white"),
        np.where(L[ach] < BLACK_L, VOCABULARY.index("black"), VOCABULARY.index("gray")),
    )
    code[band] = -1
    return code, lab[:, 0].copy()


_SRGB_TO_LIN = ((np.arange(256) / 255.0 + 0.055) / 1.055) ** 2.4
_SRGB_TO_LIN[:11] = np.arange(11) / 255.0 / 12.92
_LUMA = np.array([0.2126, 0.7152, 0.0722])


def _srgb(lin: np.ndarray) -> np.ndarray:
    lin = np.clip(lin, 0.0, 1.0)
    v = np.where(lin <= 0.0031308, 12.92 * lin, 1.055 * np.power(lin, 1 / 2.4) - 0.055)
    return np.clip(np.rint(v * 255.0), 0, 255).astype(np.uint8)


def image_white(rgb: np.ndarray) -> float:
    """The picture's white level: the WHITE_QUANTILE of its linear luminance (on a 4x thinned grid). Why:
    a white object in a photo or a render is rarely 255; people judge it against the brightest things in
    view (white-patch colour constancy), so pixels are scaled by 1 / white level before naming."""
    lin = _SRGB_TO_LIN[np.asarray(rgb, np.uint8)[::4, ::4].reshape(-1, 3)]
    return float(np.quantile(lin @ _LUMA, WHITE_QUANTILE)) if len(lin) else 1.0


def unshade(px: np.ndarray, white: float = 1.0) -> np.ndarray:
    """Pixels with the shading taken out: each pixel's linear RGB scaled towards the object's lit
    luminance (its LIT_QUANTILE), the gain capped at MAX_GAIN. Why: shading multiplies a matte
    surface's linear RGB by one factor, so a shaded yellow flank becomes olive or brown; undoing a
    factor up to MAX_GAIN restores it, while a black part of a white object (far darker than any
    shadow) stays dark. The brightest HIGHLIGHT_QUANTILE (specular highlights) are dropped."""
    lin = _SRGB_TO_LIN[px] * min(1.0 / max(white, 1e-3), MAX_EXPOSURE)
    y = lin @ _LUMA
    ref, top = np.quantile(y, [LIT_QUANTILE, 1.0 - HIGHLIGHT_QUANTILE])
    keep = y <= top
    lin, y = lin[keep], y[keep]
    gain = np.clip(ref / np.maximum(y, 1e-4), 1.0, MAX_GAIN)
    return _srgb(lin * gain[:, None])


def colour_shares(rgb_pixels: np.ndarray, white: float = 1.0) -> dict[str, float]:
    """Share of the (unshaded) pixels per basic term ("" = between terms) for (N, 3) uint8 sRGB pixels."""
    px = np.asarray(rgb_pixels, np.uint8)
    if len(px) > MAX_PIXELS:  # deterministic subsample: shares change by well under 1%
        px = px[:: int(np.ceil(len(px) / MAX_PIXELS))]
    q = (unshade(px, white) >> 3).astype(np.int32)
    code = _lut()[0][(q[:, 0] * LUT_LEVELS + q[:, 1]) * LUT_LEVELS + q[:, 2]]
    counts = np.bincount(code + 1, minlength=len(VOCABULARY) + 1)
    n = len(code)
    out = {NONE: int(counts[0]) / n} if counts[0] else {}
    out.update({w: int(counts[k + 1]) / n for k, w in enumerate(VOCABULARY) if counts[k + 1]})
    return out


def colour_word(
    rgb_pixels: np.ndarray,
    given: str | None = None,
    category: str | None = None,
    min_share: float = MIN_SHARE,
    margin: float = MARGIN,
    white: float = 1.0,
) -> tuple[str | None, str]:
    """(word or None, how): "pixels" | "source" | "margin" (no clear winner) | "person_or_animal"
    | "too_few_pixels". `white`: the picture's `image_white` (1.0: pixels as they are)."""
    if never_coloured(category):
        return None, "person_or_animal"
    if len(rgb_pixels) < MIN_PIXELS:
        return None, "too_few_pixels"
    shares = colour_shares(rgb_pixels, white)
    ranked = sorted(shares, key=lambda w: (-shares[w], w))
    best = ranked[0]
    second = shares[ranked[1]] if len(ranked) > 1 else 0.0
    if best != NONE and shares[best] >= min_share and shares[best] - second >= margin:
        return best, "pixels"
    g = _ALIASES.get((given or "").lower(), (given or "").lower())
    if best != NONE and g == best:
        return g, "source"
    return None, "margin"


def colour_lab(rgb_pixels: np.ndarray, white: float = 1.0) -> tuple[float, float, float] | None:
    """The object's colour as one CIELAB point: the per-channel median of its unshaded pixels (the pixels
    `colour_shares` names). Why: two objects can get different basic terms while looking alike (a tan
    basket "brown", a light one "white" beside a "gray" one); a colour word may only tell two objects apart
    when their colours are also far apart (`distinct_colours`). None with too few pixels."""
    px = np.asarray(rgb_pixels, np.uint8)
    if len(px) < MIN_PIXELS:
        return None
    if len(px) > MAX_PIXELS:
        px = px[:: int(np.ceil(len(px) / MAX_PIXELS))]
    lab = _lab(unshade(px, white).astype(np.float32) / 255.0)
    med = np.median(lab, axis=0)
    return (round(float(med[0]), 2), round(float(med[1]), 2), round(float(med[2]), 2))


def delta_e(a: tuple[float, float, float] | list[float], b: tuple[float, float, float] | list[float]) -> float:
    """CIE76 colour difference (Euclidean distance in CIELAB)."""
    return float(np.sqrt(sum((float(x) - float(y)) ** 2 for x, y in zip(a, b))))


def mask_pixels(rgb: np.ndarray, mask: np.ndarray) -> np.ndarray:
    """sRGB pixels of the mask's interior (eroded by one pixel when enough remain, to skip edges mixed
    with the background), thinned to at most MAX_PIXELS as `colour_shares` thins them."""
    import cv2

    inner = cv2.erode(mask.astype(np.uint8), np.ones((3, 3), np.uint8)).astype(bool)
    m = inner if inner.sum() >= MIN_PIXELS else mask.astype(bool)
    pix = rgb[m]
    if len(pix) > MAX_PIXELS:
        pix = pix[:: int(np.ceil(len(pix) / MAX_PIXELS))]
    return pix
