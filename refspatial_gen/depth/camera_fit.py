"""Per-photo camera height and pitch from the objects standing on the ground (geometric depth).

The geometric prior (camera 1.5 m high, level) is right for few photos: street photos taken from a
bus, a child's height or a balcony lift people 0.2 to 3.7 m tall. But objects of known size fix the
camera, as in Hoiem, Efros & Hebert, "Putting Objects in Perspective" (CVPR 2006): for a camera at
height h pitched down by theta, an upright object whose bottom row makes the angle b and whose top row
makes the angle t below the optical axis has height

    H = h * (1 - tan(theta + t) / tan(theta + b)),

linear in h. Each anchor (a ground-standing object of a ranged category, contact and top visible)
turns its category's height range into an interval of admissible log h for every pitch. The fit takes,
over a grid of pitches, the height stabbed by the most intervals (a robust consensus: a sitting person,
a toddler or a mislabelled object is simply outvoted), ties broken by the least robust (Cauchy)
deviation from the typical heights plus the prior terms. The whole photo shares one camera: no object is forced to its
typical size. With no anchor the prior stays; with fewer than `min_anchors` agreeing anchors the fit is
used but the frame's metric scale is "unverified" (one object fits any camera); when fewer than
`min_inlier_share` of the anchors agree it is "inconsistent" (docs/image.md, docs/quality.md).
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from refspatial_gen.truth.sizes import size_range

MIN_BELOW_HORIZON = np.deg2rad(0.5)  # a contact this close to the horizon gives no usable distance
TYPICAL_SPREAD = 0.12  # log-height spread of one category around its typical height (adults: about +-10 %)


@dataclass(frozen=True)
class Anchor:
    """One ground-standing object: its category and the continuous rows of its lowest and highest
    mask edges (bottom = lower edge of the lowest row, top = upper edge of the highest row)."""

    key: int
    category: str
    v_bottom: float
    v_top: float


@dataclass
class CameraFit:
    camera_height: float
    pitch: float  # radians, > 0 looks down
    source: str  # "fit" | "prior"
    anchors: int = 0
    inliers: list[int] = field(default_factory=list)  # anchor keys within their range
    status: str = "unverified"  # "consistent" | "inconsistent" | "unverified"

    def meta(self) -> dict:
        return {
            "source": self.source,
            "camera_height": round(self.camera_height, 4),
            "pitch_deg": round(float(np.rad2deg(self.pitch)), 3),
            "anchors": self.anchors,
            "inliers": len(self.inliers),
            "status": self.status,
            "reliable": self.status == "consistent",
        }


def anchor_usable(category: str) -> bool:
    r = size_range(category)
    return r is not None and r.anchor and r.height is not None and r.typical is not None


def _stab(lo: np.ndarray, hi: np.ndarray) -> tuple[int, float, float]:
    """Largest number of intervals [lo_i, hi_i] sharing a point, and that shared interval."""
    ev = np.concatenate([np.c_[lo, np.ones_like(lo)], np.c_[hi, -np.ones_like(hi)]])
    ev = ev[np.lexsort((-ev[:, 1], ev[:, 0]))]  # at equal positions open before close
    run = np.cumsum(ev[:, 1])
    k = int(np.argmax(run))
    return int(run[k]), float(ev[k, 0]), float(ev[k + 1, 0]) if k + 1 < len(ev) else float(ev[k, 0])


def fit_camera(
    anchors: list[Anchor],
    fy: float,
    cy: float,
    prior_height: float,
    prior_pitch: float,
    pitch_range: tuple[float, float] = (-15.0, 45.0),
    height_range: tuple[float, float] = (0.3, 30.0),
    min_inlier_share: float = 0.6,
    prior_sigma_pitch_deg: float = 10.0,
    prior_sigma_log_height: float = 0.7,
    min_anchors: int = 2,
) -> CameraFit:
    """Camera height (m) and pitch (rad) that put the most anchors inside their category's height range.

    `pitch_range` (degrees) and `height_range` (metres) bound the search; ties between equally
    supported cameras go to the least squared deviation (in log height) from the typical heights plus
    the prior terms. See the module docstring."""
    use = [a for a in anchors if anchor_usable(a.category) and a.v_bottom > a.v_top]
    if not use:
        return CameraFit(prior_height, prior_pitch, "prior", 0, [], "unverified")
    ranges = [size_range(a.category) for a in use]
    lo_h = np.log([r.height[0] for r in ranges])
    hi_h = np.log([r.height[1] for r in ranges])
    typ = np.log([r.typical for r in ranges])
    ab = np.arctan((np.array([a.v_bottom for a in use]) - cy) / fy)
    at = np.arctan((np.array([a.v_top for a in use]) - cy) / fy)
    lh0, lh1 = np.log(height_range[0]), np.log(height_range[1])

    def score(deg: float):
        th = np.deg2rad(deg)
        ok = (th + ab) > MIN_BELOW_HORIZON
        if not ok.any():
            return None
        g = 1.0 - np.tan(th + at[ok]) / np.tan(th + ab[ok])
        ok_idx = np.flatnonzero(ok)[g > 1e-6]
        g = g[g > 1e-6]
        if not len(g):
            return None
        lg = np.log(g)
        lo, hi = np.clip(lo_h[ok_idx] - lg, lh0, lh1), np.clip(hi_h[ok_idx] - lg, lh0, lh1)
        count, a, b = _stab(lo, hi)
        inside = (lo <= a + 1e-12) & (hi >= b - 1e-12)
        # best log h inside the shared interval: robust (Cauchy) agreement with the inliers' typical
        # heights, so a toddler or a sitting person inside the range does not drag the camera
        t = typ[ok_idx][inside] - lg[inside]
        grid = np.unique(np.concatenate([np.linspace(a, b, 41), np.clip(t, a, b)]))
        c = (
            np.log1p(((grid[:, None] - t[None, :]) / TYPICAL_SPREAD) ** 2).sum(axis=1)
            + ((grid - np.log(prior_height)) / prior_sigma_log_height) ** 2
        )
        k = int(np.argmin(c))
        cost = float(c[k] + ((deg - np.rad2deg(prior_pitch)) / prior_sigma_pitch_deg) ** 2)
        return (count, -cost), th, float(grid[k]), [use[i].key for i in ok_idx[inside]]

    # coarse to fine: 1 degree steps over the range, then 0.1 degree around the best
    best = None
    for deg in np.arange(pitch_range[0], pitch_range[1] + 1e-9, 1.0):
        r = score(float(deg))
        if r is not None and (best is None or r[0] > best[0]):
            best = r
    if best is not None:
        c0 = float(np.rad2deg(best[1]))
        for deg in np.arange(max(pitch_range[0], c0 - 1.0), min(pitch_range[1], c0 + 1.0) + 1e-9, 0.1):
            r = score(float(deg))
            if r is not None and r[0] > best[0]:
                best = r
    if best is None:
        return CameraFit(prior_height, prior_pitch, "prior", len(use), [], "inconsistent")
    (count, _), th, lh, keys = best
    if count < min_inlier_share * len(use):
        status = "inconsistent"
    else:  # one object fits any camera: agreement is only evidence from `min_anchors` on
        status = "consistent" if count >= min_anchors else "unverified"
    return CameraFit(float(np.exp(lh)), float(th), "fit", len(use), sorted(keys), status)


def implied_height(
    camera_height: float, pitch: float, fy: float, cy: float, v_bottom: float, v_top: float
) -> float | None:
    """Height of an upright object standing on the ground with these edge rows (None: contact at or
    above the horizon)."""
    b = pitch + np.arctan((v_bottom - cy) / fy)
    if b <= MIN_BELOW_HORIZON:
        return None
    t = pitch + np.arctan((v_top - cy) / fy)
    return float(camera_height * (1.0 - np.tan(t) / np.tan(b)))
