"""Object-level filters with counted reasons, applied after lifting.

Why the category rule exists: a question says "the leftmost cup"; if one cup of the picture was dropped
(too small, no depth), the answer may no longer be the leftmost cup in the picture. So when any
instance of a category is dropped, all its instances are dropped (`category_incomplete`), and a
category whose instances sit on top of each other in 3D (duplicate or crowd-like annotations, whose
ordinal phrases would be unstable) is dropped as `instances_not_spread`.
"""

from __future__ import annotations

from collections import Counter
from dataclasses import dataclass, field

import numpy as np


@dataclass
class Candidate:
    """An object on its way into the Frame; `reason` set = dropped."""

    ann_id: str
    category: str
    mask: np.ndarray
    bbox2d: tuple[float, float, float, float]
    segmentation: bool  # True: a real mask; False: the annotation was a box
    iscrowd: bool = False
    box: object = None  # Box3D once lifted
    reason: str | None = None
    provenance: dict = field(default_factory=dict)


def drop(c: Candidate, reason: str) -> None:
    if c.reason is None:
        c.reason = reason


def instances_not_spread(cands: list[Candidate], min_spread: float) -> None:
    """Drop categories with several instances whose 3D centres have a nearest-neighbour distance below
    `min_spread` metres (median over instances)."""
    by_cat: dict[str, list[Candidate]] = {}
    for c in cands:
        if c.reason is None and c.box is not None:
            by_cat.setdefault(c.category, []).append(c)
    for cat in sorted(by_cat):
        group = by_cat[cat]
        if len(group) < 2:
            continue
        P = np.array([c.box.center for c in group])
        D = np.linalg.norm(P[:, None] - P[None], axis=-1)
        np.fill_diagonal(D, np.inf)
        if float(np.median(D.min(axis=1))) < min_spread:
            for c in group:
                drop(c, "instances_not_spread")


def too_many_instances(cands: list[Candidate], max_instances: int) -> None:
    counts = Counter(c.category for c in cands if c.reason is None)
    for c in cands:
        if c.reason is None and counts[c.category] > max_instances:
            drop(c, "too_many_instances")


def complete_categories(cands: list[Candidate], crowd_categories: set[str]) -> None:
    """Drop every instance of a category that lost an instance or has a crowd annotation."""
    bad = set(crowd_categories) | {c.category for c in cands if c.reason is not None}
    for c in cands:
        if c.reason is None and c.category in bad:
            drop(c, "category_incomplete")


def resolve_overlaps(cands: list[Candidate]) -> int:
    """Make visible masks disjoint: a pixel claimed by several objects goes to the smallest mask (in a
    photo the smaller of two overlapping annotations is nearly always the one in front or on top).
    Returns the number of reassigned pixels."""
    live = [c for c in cands if c.reason is None]
    if len(live) < 2:
        return 0
    order = sorted(live, key=lambda c: (int(c.mask.sum()), c.ann_id))
    taken = np.zeros_like(order[0].mask, dtype=bool)
    moved = 0
    for c in order:
        overlap = c.mask & taken
        k = int(overlap.sum())
        if k:
            moved += k
            c.mask = c.mask & ~taken
        taken |= c.mask
    return moved


def drop_counts(cands: list[Candidate]) -> dict[str, int]:
    return dict(sorted(Counter(c.reason for c in cands if c.reason is not None).items()))


def incomplete_categories(annotations: list, crowd: set[str], cfg: dict) -> dict[str, str]:
    """Categories of the photo whose annotated instances may not be all there are, with why: a crowd
    region of it (`crowd`), at least `incomplete_min_instances` annotated (`many_instances`: annotators
    stop outlining one by one), or listed in `incomplete_categories` (`listed`: COCO leaves background
    people unannotated, audit round 2 item 5802). No claim over the whole category is made then
    (qa/faint_photo.py): "the leftmost person" may not be."""
    counts: dict[str, int] = {}
    for a in annotations:
        if a.isthing and not a.iscrowd:
            counts[a.category] = counts.get(a.category, 0) + 1
    listed = set(cfg["incomplete_categories"] or [])
    out: dict[str, str] = {}
    for cat in sorted(set(counts) | crowd):
        if cat in crowd:
            out[cat] = "crowd"
        elif counts[cat] >= int(cfg["incomplete_min_instances"]):
            out[cat] = "many_instances"
        elif cat in listed:
            out[cat] = "listed"
    return out
