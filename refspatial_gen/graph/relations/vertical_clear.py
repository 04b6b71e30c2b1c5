"""World above/below a person signs off: over it, or clearly higher beside it (audit pre-round 5).

Why: "the computer mouse is physically above the tray" was answered yes for a mouse on a thin book lying
on the table behind the tray: its bottom (the book's top, ~3.5 cm) was at the tray's rim (3.3 cm), so the
stack rule called it above, though it is not over the tray and hardly higher. A is above B when
  - their footprints overlap (the larger share of either footprint over the other at least
    `vertical_over_share`) and A's bottom is at or above B's top (a resting stack, as before), or
  - they do not overlap and A's bottom is above B's top by a clear gap:
    max(`vertical_clear_margin`, `vertical_clear_share` x B's height).
Otherwise the pair is undecided (counted as `vertical_beside_margin` where the old stack rule decided it).
qa/verify_vertical.py re-checks every asked pair by its own code.
"""

from __future__ import annotations

import numpy as np

from refspatial_gen.graph.constants import Thresholds
from refspatial_gen.graph.relations.common import FALSE, TRUE, UNDECIDED, count
from refspatial_gen.graph.scene import SceneGeom


def clear_gap_needed(th: Thresholds, height_b: np.ndarray | float) -> np.ndarray:
    """The gap (m) A's bottom must clear above B's top when A is beside B, not over it."""
    return np.maximum(th.vertical_clear_margin, th.vertical_clear_share * np.asarray(height_b, float))


def apply_clear_margin(g: SceneGeom, codes: np.ndarray) -> None:
    """Withhold (in place) decided above/below pairs whose footprints do not overlap and whose vertical gap
    is below the clear gap; count them as `vertical_beside_margin`."""
    share = np.maximum(g.footprint_overlap, g.footprint_overlap.T)
    over = share >= g.th.vertical_over_share
    gap = g.lo[:, None, 2] - g.hi[None, :, 2]  # gap[i, j]: i's bottom above j's top (m)
    clear = gap >= clear_gap_needed(g.th, g.hi[None, :, 2] - g.lo[None, :, 2])
    ok = over | np.where(codes == TRUE, clear, False) | np.where(codes == FALSE, clear.T, False)
    beside = (codes != UNDECIDED) & ~ok
    count(g, "vertical_beside_margin", beside)
    codes[beside] = UNDECIDED
