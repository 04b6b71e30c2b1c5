"""Typical upright heights (metres) of common object categories (COCO and SUN RGB-D names).

Used by the geometric estimator as a sanity check: an object whose contact-based distance implies it is
more than `max_size_ratio` times taller than typical was placed by a wrong contact (a toaster on an
unannotated counter read as standing on the far floor) and is dropped. Only the upper side is checked:
occlusion and truncation make visible heights smaller, never larger. Categories whose height depends on
pose or orientation (skis, knives, kites, frisbees, surfboards...) have no entry and are not checked.
"""

from __future__ import annotations

TYPICAL_HEIGHT_M: dict[str, float] = {
    "person": 1.7, "bicycle": 1.0, "car": 1.5, "motorcycle": 1.1, "airplane": 12.0, "bus": 3.2, "train": 4.0,
    "truck": 3.0, "fire hydrant": 0.8, "parking meter": 1.4, "bench": 0.9, "bird": 0.3, "cat": 0.3, "dog": 0.6,
    "horse": 1.6, "sheep": 0.9, "cow": 1.4, "elephant": 3.0, "bear": 1.2, "zebra": 1.4, "giraffe": 5.0,
    "backpack": 0.5, "umbrella": 1.0, "handbag": 0.35, "suitcase": 0.65, "sports ball": 0.22,
    "baseball glove": 0.3, "bottle": 0.28, "wine glass": 0.2, "cup": 0.11, "bowl": 0.1, "apple": 0.08,
    "orange": 0.08, "sandwich": 0.1, "broccoli": 0.15, "cake": 0.15, "chair": 0.95, "couch": 0.9,
    "potted plant": 0.6, "bed": 1.0, "dining table": 0.75, "toilet": 0.8, "tv": 0.6, "laptop": 0.25,
    "mouse": 0.04, "microwave": 0.3, "oven": 0.9, "toaster": 0.2, "refrigerator": 1.8, "book": 0.24,
    "clock": 0.35, "vase": 0.3, "teddy bear": 0.4, "hair drier": 0.25,
    # SUN RGB-D
    "table": 0.75, "desk": 0.75, "sofa": 0.9, "night_stand": 0.6, "dresser": 0.9, "lamp": 0.6, "ottoman": 0.45,
    "bookshelf": 1.8, "sofa_chair": 0.9, "garbage_bin": 0.6, "monitor": 0.45, "pillow": 0.5, "box": 0.4,
}


def typical_height(category: str) -> float | None:
    return TYPICAL_HEIGHT_M.get(category.lower())
