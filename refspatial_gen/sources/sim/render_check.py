"""Do two renderers agree on a frame's geometry? Per-object mask IoU and per-pixel depth agreement.

Used when the RGB comes from Blender while the frame's masks and depth come from MuJoCo (the geometry
reference, see docs/sim.md): if Blender's own depth and object-index passes do not show the same
objects at the same pixels and distances, the photo and its labels would not match, and the unit is
dropped with `DropUnit("renderer_disagree")`.
"""

from __future__ import annotations

from typing import Any

import numpy as np


def agreement(
    ref_depth: np.ndarray,
    ref_ids: np.ndarray,
    depth: np.ndarray,
    ids: np.ndarray,
    *,
    min_pixels: int,
    depth_tol: float,
    depth_rel_tol: float,
) -> dict[str, Any]:
    """Mask IoU of every object that covers >= `min_pixels` in either render, and the fraction of pixels
    with geometry in either render whose depths agree within `depth_tol + depth_rel_tol * z` (a pixel
    with geometry in one render only disagrees)."""
    ious: dict[int, float] = {}
    for k in np.union1d(np.unique(ref_ids), np.unique(ids)):
        if k <= 0:
            continue
        a, b = ref_ids == k, ids == k
        na, nb = int(a.sum()), int(b.sum())
        if max(na, nb) < min_pixels:
            continue
        ious[int(k)] = float((a & b).sum() / (a | b).sum())
    seen = (ref_depth > 0) | (depth > 0)
    both = (ref_depth > 0) & (depth > 0)
    close = both & (np.abs(depth - ref_depth) <= depth_tol + depth_rel_tol * ref_depth)
    n = int(seen.sum())
    worst = min(ious, key=lambda k: (ious[k], k)) if ious else None
    return {
        "objects": len(ious),
        "mask_iou_mean": round(float(np.mean(list(ious.values()))), 4) if ious else 1.0,
        "mask_iou_min": round(ious[worst], 4) if ious else 1.0,
        "worst_id": worst,
        "depth_agree": round(float(close.sum() / n), 4) if n else 1.0,
    }


def disagreement(stats: dict[str, Any], min_iou: float, min_depth_agree: float) -> str | None:
    """Why the two renders disagree too much (None when they agree)."""
    if stats["mask_iou_min"] < min_iou:
        return f"object {stats['worst_id']} mask IoU {stats['mask_iou_min']:.3f} < {min_iou}"
    if stats["depth_agree"] < min_depth_agree:
        return f"depth agrees on {stats['depth_agree']:.3f} of pixels < {min_depth_agree}"
    return None
