"""The receptacle rule of "inside": B must be able to hold A inside it, and A must lie in B's interior.

Why: "inside" is decided on the share of A's box volume in B's box (containment.py `_inside`), and a box
encloses more than its object: ScanNet's desk box spans the desk and a wooden post at its end, so the bin
standing on the floor beside the desk's panel had 88% of its box in the desk's and became "the bin in the
desk" (audit round 4, wrong); a coffee table in the L of a sofa's box was "in the sofa". A person says "in"
for a receptacle (truth/data/containers.yaml), for a thing that fits in it, lying over its floor:

- `inside_not_container`: B's category holds nothing inside it, or nothing of A's class (a desk, a table,
  a sofa, a bed; a person in a bowl);
- `inside_does_not_fit`: A's largest horizontal extent exceeds `inside_max_overhang` (graph: thresholds:)
  times B's, or A's box is not smaller than B's (two stand-ins of one unlabelled blob share a box);
- `inside_not_interior`: A's footprint centre lies outside B's footprint, or A's bottom lies below B's
  bottom by more than `stack_tolerance` (A stands beside or under B, only overlapping its box).

A pair the volume share calls inside that fails the rule is undecided (neither "in" nor "outside" is asked),
counted by reason in graph.meta["truth"]; verify re-checks it by its own code (qa/verify_inside.py).
"""

from __future__ import annotations

import numpy as np

from refspatial_gen.graph.relations.common import FALSE, TRUE, UNDECIDED, count
from refspatial_gen.graph.scene import SceneGeom, points_in_polygons
from refspatial_gen.truth.containers import can_contain, fits

NOT_CONTAINER = "inside_not_container"
DOES_NOT_FIT = "inside_does_not_fit"
NOT_INTERIOR = "inside_not_interior"


def _sizes(g: SceneGeom) -> np.ndarray:
    """(n, 3) gravity-frame sizes: larger and smaller footprint side, height."""
    fp = g.footprints
    sides = np.linalg.norm(np.roll(fp, -1, axis=1) - fp, axis=2)[:, :2] if g.n else np.zeros((0, 2))
    return np.column_stack([sides.max(axis=1), sides.min(axis=1), g.height]) if g.n else np.zeros((0, 3))


def why_not_inside(g: SceneGeom, i: int, j: int, sizes: np.ndarray) -> str | None:
    """The reason object i (position) is not in object j by the receptacle rule, or None when it may be."""
    ci, cj = g.categories[i], g.categories[j]
    if not can_contain(cj, ci, sizes[j], sizes[i]):
        return NOT_CONTAINER
    if not fits(sizes[j], sizes[i], g.th.inside_max_overhang) or g.volume[i] >= g.volume[j]:
        return DOES_NOT_FIT
    centre = g.centers[i : i + 1, :2]
    if not points_in_polygons(centre, g.footprints[j : j + 1])[0, 0]:
        return NOT_INTERIOR
    if g.lo[i, 2] < g.lo[j, 2] - g.th.stack_tolerance:
        return NOT_INTERIOR
    return None


def apply_receptacle_rule(g: SceneGeom, codes: np.ndarray) -> np.ndarray:
    """`codes` (inside decisions from the volume share) with every pair that fails the rule undecided; the
    pairs it takes "inside" from are counted by reason in graph.meta["truth"]."""
    sizes = _sizes(g)
    out = codes.copy()
    failed: dict[str, np.ndarray] = {}
    for i, j in zip(*np.nonzero(codes != FALSE)):
        if i == j:
            continue
        why = why_not_inside(g, int(i), int(j), sizes)
        if why is None:
            continue
        if codes[i, j] == TRUE:
            failed.setdefault(why, np.zeros(codes.shape, bool))[i, j] = True
        out[i, j] = UNDECIDED
    for why in sorted(failed):
        count(g, why, failed[why])
    return out
