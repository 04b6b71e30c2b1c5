"""One mask spanning the other in the image: neither is left/right (above/below) of the other.

Why: a train spanning the whole photo behind a cyclist is on both sides of the bicycle; "left of" then
follows the occlusion-shifted centroid, not anything a person can see (audit round 4, photos image:483108
#5 and #10). A first rule ("a centroid inside the other's columns") also withheld a night stand standing at
the end of a bed whose mask reaches 0.7% of the width past it (SUN RGB-D 000001) and was reverted. Here the
wide mask must reach clearly past the other on BOTH sides: by `image_span_margin` of the image side
(width for left/right, height for above/below) beyond each end of the other mask; overlapping at one end
(side by side) stays decided. verify re-checks it from the decoded masks (qa/verify_span.py).
"""

from __future__ import annotations

import numpy as np

from refspatial_gen.graph.scene import SceneGeom


def span_contains(geom: SceneGeom, axis: int) -> np.ndarray:
    """[i, j] (symmetric): along image `axis` (0 columns, 1 rows) one of the two masks reaches at least
    `image_span_margin` of the image side beyond both ends of the other. Objects without a mask never span."""
    span = geom.img_cols if axis == 0 else geom.img_rows
    lo, hi = span[:, 0], span[:, 1]
    m = geom.th.image_span_margin
    with np.errstate(invalid="ignore"):  # NaN spans compare False
        spans = (lo[None, :] - lo[:, None] >= m) & (hi[:, None] - hi[None, :] >= m)  # [i, j]: i's mask spans j's
    return spans | spans.T
