"""What a reader hands to the frame builder: one posed view with its boxes, before visibility.

Readers only parse files and convert conventions (units, pixel origin, axes, gravity); everything that
decides what is visible (depth clipping, masks, fractions, keyframe checks) lives in `frames.py`, so the
same rules apply to every scan format.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Any

import numpy as np

from refspatial_gen.core.camera import Camera
from refspatial_gen.core.geometry import Box3D


@dataclass(eq=False)
class ScanBox:
    """An annotated oriented box in the view's world frame. `id` > 0 and stable across views of a scene."""

    id: int
    category: str
    box: Box3D
    front: np.ndarray | None = None  # unit vector in the box frame
    front_phrase: str | None = None
    name: str | None = None
    attributes: dict[str, str] = field(default_factory=dict)
    provenance: dict[str, Any] = field(default_factory=dict)


@dataclass(eq=False)
class ScanView:
    """One RGB-D view. `depth` may be None when `points` (a world point cloud) is given to splat instead.

    `boxes_per_frame` is True when the boxes were annotated for this very view (SUN RGB-D): a box behind
    the camera then means broken input. Scene-level boxes (ScanNet) are simply out of view.
    `gravity_source` says how the world frame was made z-up ("rtilt", "scan_z_up", "given",
    "floor_plane") or "unknown" (then `camera.gravity_known` is False).
    """

    reader: str
    scene_id: str
    view_id: str
    rgb: np.ndarray
    depth: np.ndarray | None
    camera: Camera
    boxes: list[ScanBox]
    gravity_source: str
    boxes_per_frame: bool = False
    points: np.ndarray | None = None
    meta: dict[str, Any] = field(default_factory=dict)
    point_labels: np.ndarray | None = None  # per-point instance id (0 = none), aligned with `points`
    box_instance: dict[int, int] = field(default_factory=dict)  # box id -> its instance id in point_labels


def boxes_to_world(boxes: list[ScanBox], T: np.ndarray) -> list[ScanBox]:
    """Apply a rigid world transform (4x4) to boxes (used when a reader re-levels its world frame)."""
    T = np.asarray(T, float)
    out = []
    for b in boxes:
        nb = Box3D(T[:3, :3] @ b.box.center + T[:3, 3], b.box.size, T[:3, :3] @ b.box.rotation)
        out.append(
            ScanBox(b.id, b.category, nb, b.front, b.front_phrase, b.name, dict(b.attributes), dict(b.provenance))
        )
    return out
