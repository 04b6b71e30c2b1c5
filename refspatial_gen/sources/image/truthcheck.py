"""Truth checks of the image source: the photo's camera fitted to its objects, and lifted sizes checked
against their category's range (refspatial_gen/truth). See docs/image.md and docs/quality.md.

- `fit_photo_camera`: geometric depth only. Objects of ranged, ground-standing categories whose foot
  and top are in the picture and that have no other object under their foot fix the camera height and
  pitch of the whole photo (depth/camera_fit.py); the recipe's camera is the prior.
- `check_sizes`: after lifting, an object whose box is outside its category's range is removed
  (reason `size_too_tall`, `size_too_short`, ...; counted in `frame.meta["truth"]`). Extents a single
  view cannot see whole are only checked from above: the horizontal extent always, the height when
  the top is cut by the image border or (measured depth) always, since nothing completes a hidden
  foot there. Unranged categories are kept and marked `provenance["size_check"] = "size_unranged"`:
  the graph must not ask metric or size questions about them.
"""

from __future__ import annotations

from typing import Any

import numpy as np

from refspatial_gen.depth.camera_fit import Anchor, CameraFit, anchor_usable, fit_camera
from refspatial_gen.truth.sizes import IMPLAUSIBLE, UNRANGED, check_size


def photo_anchors(cands: list, H: int, W: int, cfg_share: float = 0.1) -> list[Anchor]:
    """Anchors for the camera fit: live candidates of anchor categories, foot and top inside the
    picture, no other object's mask right under `cfg_share` of the foot (it might rest on it or stand
    behind it)."""
    from refspatial_gen.depth.geometric import _Obj, object_below

    ids = np.zeros((H, W), np.int64)
    for k, c in enumerate(cands):
        ids[c.mask & (ids == 0)] = k + 1
    out = []
    for k, c in enumerate(cands):
        if not anchor_usable(c.category):
            continue
        ys, xs = np.nonzero(c.mask)
        if ys.size == 0 or ys.max() >= H - 1 or ys.min() <= 0:
            continue
        o = _Obj(k + 1, c.mask, ys, xs, int(ys.max()), 0.0, c.category)
        b, share = object_below(o, ids)
        if b and share >= float(cfg_share) and np.nonzero(cands[b - 1].mask.any(axis=1))[0].max() > o.vb:
            continue
        out.append(Anchor(k + 1, c.category, float(ys.max() + 1), float(ys.min())))
    return out


def fit_photo_camera(
    cands: list, H: int, W: int, fy: float, cy: float, cam_h: float, pitch: float, cfg: dict[str, Any]
) -> CameraFit:
    """The photo's camera (height, pitch) from its anchors, the recipe's values as the prior."""
    if not cfg.get("fit_camera", True):
        return CameraFit(cam_h, pitch, "prior", 0, [], "unverified")
    lo_p, hi_p = (float(x) for x in cfg["fit_pitch_range_deg"])
    lo_h, hi_h = (float(x) for x in cfg["fit_height_range"])
    return fit_camera(
        photo_anchors(cands, H, W),
        fy,
        cy,
        cam_h,
        pitch,
        (lo_p, hi_p),
        (lo_h, hi_h),
        float(cfg["fit_min_inlier_share"]),
        min_anchors=int(cfg["fit_min_anchors"]),
    )


def check_sizes(cands: list, cfg: dict[str, Any], measured: bool, truth: dict[str, int]) -> None:
    """Drop lifted candidates outside their category's range (see the module docstring); counts the
    reasons into `truth`."""
    from refspatial_gen.sources.image.filters import drop

    for c in cands:
        if c.reason is not None or c.box is None:
            continue
        top_cut = bool(np.nonzero(c.mask.any(axis=1))[0].min() == 0) if c.mask.any() else True
        lower = {"extent", "length"}
        if measured or top_cut:
            lower.add("height")
        why = check_size(
            c.category,
            c.box.size,
            dims=("height", "length", "extent"),
            tolerance=float(cfg["size_tolerance"]),
            lower_bounds=lower,
        )
        if why == UNRANGED:
            c.provenance["size_check"] = UNRANGED
        elif why in IMPLAUSIBLE:
            c.provenance["size_check"] = why
            if cfg.get("size_check", True):
                drop(c, why)
                truth[why] = truth.get(why, 0) + 1
        else:
            c.provenance["size_check"] = "in_range"


def _overlap_share(a, b) -> float:
    """Volume shared by two gravity-aligned boxes over the smaller one's volume (footprints as polygons)."""
    import shapely

    pa, pb = shapely.Polygon(a.footprint()), shapely.Polygon(b.footprint())
    dz = min(a.top_z, b.top_z) - max(a.bottom_z, b.bottom_z)
    if dz <= 0:
        return 0.0
    v = pa.intersection(pb).area * dz
    return float(v / max(min(a.volume, b.volume), 1e-9))


def check_interpenetration(cands: list, max_share: float, truth: dict[str, int]) -> None:
    """Geometric depth: solid things do not pass through each other. Two lifted boxes sharing more than
    `max_share` of the smaller one's volume mean one was placed wrongly (a bicycle half hidden behind a
    girl, its foot read as nearer than hers) or that one is inside the other in a way billboards cannot
    tell (a rider's box through the elephant's): the one with the smaller mask is removed
    (`boxes_interpenetrate`), so no question claims one is inside the other."""
    from refspatial_gen.sources.image.filters import drop

    live = [c for c in cands if c.reason is None and c.box is not None]
    for i, a in enumerate(live):
        for b in live[i + 1 :]:
            if a.reason is not None or b.reason is not None:
                continue
            if _overlap_share(a.box, b.box) > max_share:
                loser = min((a, b), key=lambda c: (int(c.mask.sum()), c.ann_id))
                drop(loser, "boxes_interpenetrate")
                truth["boxes_interpenetrate"] = truth.get("boxes_interpenetrate", 0) + 1
