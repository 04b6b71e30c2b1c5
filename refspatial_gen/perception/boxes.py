"""Detections: per-category thresholds, non-maximum suppression, one name per box, one box per object.

Open-vocabulary detectors return overlapping boxes: several boxes for one object under one name (NMS
within the name removes them) and one box under several names ("cup" and "mug" on the same cup). RefSpatial
keeps boxes one-to-one with objects; here a box that overlaps a higher-scoring box of another name by at
least `duplicate_iou` is the same object and is dropped (`duplicate_label`). `match_one_to_one` pairs two
box sets (detections and reference annotations, or detections across captioners) by maximum total IoU
(Hungarian assignment), each box in at most one pair. Every decision is deterministic: ties break on
name, then coordinates, never on arrival order.
"""

from __future__ import annotations

from collections import Counter
from dataclasses import dataclass, field

import numpy as np


@dataclass
class Detection:
    box: tuple[float, float, float, float]  # x0, y0, x1, y1 in pixels (corner convention)
    score: float
    label: str
    meta: dict = field(default_factory=dict)

    def area(self) -> float:
        return max(0.0, self.box[2] - self.box[0]) * max(0.0, self.box[3] - self.box[1])


def iou_matrix(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """Pairwise IoU of (N,4) and (M,4) x0y0x1y1 boxes."""
    a = np.asarray(a, float).reshape(-1, 4)
    b = np.asarray(b, float).reshape(-1, 4)
    x0 = np.maximum(a[:, None, 0], b[None, :, 0])
    y0 = np.maximum(a[:, None, 1], b[None, :, 1])
    x1 = np.minimum(a[:, None, 2], b[None, :, 2])
    y1 = np.minimum(a[:, None, 3], b[None, :, 3])
    inter = np.clip(x1 - x0, 0, None) * np.clip(y1 - y0, 0, None)
    area_a = np.clip(a[:, 2] - a[:, 0], 0, None) * np.clip(a[:, 3] - a[:, 1], 0, None)
    area_b = np.clip(b[:, 2] - b[:, 0], 0, None) * np.clip(b[:, 3] - b[:, 1], 0, None)
    union = area_a[:, None] + area_b[None, :] - inter
    return np.where(union > 0, inter / np.where(union > 0, union, 1.0), 0.0)


def _order(dets: list[Detection]) -> list[Detection]:
    return sorted(dets, key=lambda d: (-round(d.score, 6), d.label, tuple(round(x, 3) for x in d.box)))


def nms(dets: list[Detection], iou: float) -> tuple[list[Detection], list[Detection]]:
    """Greedy NMS over the given detections (callers group by name) -> (kept, suppressed)."""
    order = _order(dets)
    if not order:
        return [], []
    M = iou_matrix(np.array([d.box for d in order]), np.array([d.box for d in order]))
    alive = np.ones(len(order), bool)
    for i in range(len(order)):
        if alive[i]:
            later = np.arange(len(order)) > i
            alive &= ~(later & (M[i] >= iou))
    return [d for d, a in zip(order, alive) if a], [d for d, a in zip(order, alive) if not a]


def one_to_one(dets: list[Detection], duplicate_iou: float) -> tuple[list[Detection], list[Detection]]:
    """Across names: a box overlapping a better box of another name by >= duplicate_iou is the same object."""
    order = _order(dets)
    kept: list[Detection] = []
    dropped: list[Detection] = []
    for d in order:
        if kept and iou_matrix(np.array([d.box]), np.array([k.box for k in kept]))[0].max() >= duplicate_iou:
            dropped.append(d)
        else:
            kept.append(d)
    return kept, dropped


def select(
    dets: list[Detection],
    width: int,
    height: int,
    *,
    threshold: float,
    thresholds: dict | None,
    nms_iou: float,
    duplicate_iou: float,
    max_detections: int,
    min_box_fraction: float,
    max_box_fraction: float,
) -> tuple[list[Detection], dict[str, int]]:
    """The detector's raw boxes -> kept detections (best first) and counts of what was dropped, by reason."""
    drops: Counter = Counter()
    per_cat = thresholds or {}
    img_area = float(width * height)
    live = []
    for d in dets:
        x0, y0, x1, y1 = d.box
        d.box = (
            max(0.0, min(x0, width)),
            max(0.0, min(y0, height)),
            max(0.0, min(x1, width)),
            max(0.0, min(y1, height)),
        )
        if d.score < float(per_cat.get(d.label, threshold)):
            drops["below_threshold"] += 1
        elif d.area() < min_box_fraction * img_area or d.area() <= 0:
            drops["box_too_small"] += 1
        elif d.area() > max_box_fraction * img_area:
            drops["box_too_large"] += 1
        else:
            live.append(d)
    by_name: dict[str, list[Detection]] = {}
    for d in live:
        by_name.setdefault(d.label, []).append(d)
    after_nms = []
    for name in sorted(by_name):
        k, s = nms(by_name[name], nms_iou)
        after_nms += k
        drops["nms"] += len(s)
    kept, dup = one_to_one(after_nms, duplicate_iou)
    drops["duplicate_label"] += len(dup)
    if len(kept) > max_detections:
        drops["over_max_detections"] += len(kept) - max_detections
        kept = kept[:max_detections]
    return kept, {k: v for k, v in sorted(drops.items()) if v}


def match_one_to_one(
    a: list[tuple[float, float, float, float]], b: list[tuple[float, float, float, float]], min_iou: float = 0.5
) -> list[tuple[int, int, float]]:
    """Pairs (i, j, iou) of boxes a[i], b[j] maximising the total IoU, each box in at most one pair, IoU >= min_iou."""
    if not a or not b:
        return []
    from scipy.optimize import linear_sum_assignment

    M = iou_matrix(np.array(a), np.array(b))
    rows, cols = linear_sum_assignment(-M)
    return sorted((int(i), int(j), float(M[i, j])) for i, j in zip(rows, cols) if M[i, j] >= min_iou)
