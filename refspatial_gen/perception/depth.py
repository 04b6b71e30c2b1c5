"""Metric depth and intrinsics for a photo from a depth model's prediction, with the origin of each recorded.

Intrinsics come from the first source in the recipe's order that has them: `provided` (a
`<stem>.intrinsics.json` next to the photo), `exif` (focal length tags), `model` (a depth model that
predicts the focal length: Depth Pro), `prior` (the source's `hfov_deg` field of view). A model whose
depth depends on the focal length (Depth Pro) is evaluated with the focal length chosen, so depth and
intrinsics always agree. The origin strings are those of the image source (`provided`, `exif_35mm`,
`exif_focal_plane`, `fov_prior`) plus `model:<family>`.
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

import numpy as np

from refspatial_gen.sources.image.intrinsics import Intrinsics, from_exif, from_fov, from_sidecar


@dataclass
class DepthPrediction:
    """`depth` in metres; when `per_focal`, the depth for a focal length of 1 px (multiply by f_px)."""

    depth: np.ndarray
    per_focal: bool
    focal: float | None  # the model's own focal length estimate (pixels), when it makes one


def resolve(
    order: list[str],
    image_path: Path | None,
    width: int,
    height: int,
    hfov_deg: float,
    pred: DepthPrediction | None,
    family: str | None,
) -> Intrinsics:
    """The first intrinsics source in `order` that answers; the prior always does."""
    for src in order:
        if src == "provided" and image_path is not None:
            side = from_sidecar(image_path)
            if side is not None:
                return side
        elif src == "exif" and image_path is not None:
            ex = from_exif(image_path, width, height)
            if ex is not None:
                return ex
        elif src == "model" and pred is not None and pred.focal is not None:
            f = float(pred.focal)
            return Intrinsics(f, f, width / 2.0, height / 2.0, f"model:{family}", "predicted focal length")
        elif src == "prior":
            return from_fov(width, height, hfov_deg)
    return from_fov(width, height, hfov_deg)


def metric_depth(pred: DepthPrediction, intr: Intrinsics, max_depth: float) -> np.ndarray:
    """Metres, float32; non-finite, non-positive and beyond `max_depth` become 0 (unknown)."""
    d = pred.depth * np.float32(intr.fx) if pred.per_focal else pred.depth
    d = np.asarray(d, np.float32)
    ok = np.isfinite(d) & (d > 0) & (d <= max_depth)
    return np.where(ok, d, 0.0).astype(np.float32)
