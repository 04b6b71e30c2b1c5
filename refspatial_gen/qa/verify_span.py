"""verify's own re-check of "one mask spans the other" (the generator's rule: graph/relations/span.py).

Why its own code: the generator reads normalised mask extents the graph builder measured once per frame;
this re-measures the two objects' pixel columns (rows) from the decoded masks as stored and refuses any
left/right (above/below in the image) whose one mask reaches `image_span_margin` of the image side past
both ends of the other: a train spanning the photo behind a cyclist is neither left nor right of the
bicycle. Within TOL of the margin either decision is accepted (the graph stores thresholds rounded to 1e-6).
"""

from __future__ import annotations

from typing import TYPE_CHECKING

import numpy as np

if TYPE_CHECKING:
    from refspatial_gen.qa.verify_world import World

TOL = 1e-4  # share of the image side: far below one pixel (1/640 = 0.0016)
AXIS = {"left": 0, "right": 0, "above_image": 1, "below_image": 1}  # 0 columns (width), 1 rows (height)


def _extent(w: World, oid: int, axis: int) -> tuple[int, int] | None:
    """First and last pixel index of the object's mask along the axis (None: no visible pixel)."""
    m = w.mask(oid)
    idx = np.flatnonzero(m.any(axis=axis))  # any over rows: the columns holding a pixel (and vice versa)
    return (int(idx[0]), int(idx[-1])) if len(idx) else None


def spanned(w: World, rel: str, a: int, b: int) -> str | None:
    """Why `rel(a, b)` may not be asked: one mask reaches past both ends of the other (None when it may)."""
    axis = AXIS.get(rel)
    if axis is None:
        return None
    ea, eb = _extent(w, a, axis), _extent(w, b, axis)
    if ea is None or eb is None:
        return None
    side = w.frame.camera.width if axis == 0 else w.frame.camera.height
    need = float(w.geom.th.image_span_margin) + TOL
    for (o, (lo, hi)), (p, (lo2, hi2)) in (((a, ea), (b, eb)), ((b, eb), (a, ea))):
        if (lo2 - lo) / side >= need and (hi - hi2) / side >= need:
            word = "columns" if axis == 0 else "rows"
            return f"object {o}'s mask {word} reach past both ends of object {p}'s by >= {need - TOL:.3f} of the image"
    return None
