"""Camera poses per RefSpatial: pitch 30-60 degrees below horizontal (`pitch_deg`), 0.3-0.8 m above the
support (`camera_height`), aimed at the objects; several views of one scene spread in azimuth for
multi-view questions.

Room scenes use a standing viewpoint (eye `room_eye_height`, 1.2-1.8 m above the floor) with the same
pitch range, aimed at the focus furniture group, because 0.8 m above one table cannot show a room.
"""

from __future__ import annotations

from typing import Any

import numpy as np

from refspatial_gen.core.camera import Camera, look_at
from refspatial_gen.core.geometry import Box3D


def intrinsics(width: int, height: int, fovy_deg: float) -> tuple[float, float, float, float]:
    f = height / 2 / np.tan(np.deg2rad(fovy_deg) / 2)
    return f, f, width / 2, height / 2


def _blocked(eye: np.ndarray, boxes: list[Box3D], pad: float = 0.06) -> bool:
    return any(b.contains(eye[None], pad=pad)[0] for b in boxes)


def _score(cam: Camera, centres: np.ndarray) -> int:
    uv, z = cam.project(centres)
    m = 0.06
    ok = (
        (z > 0.1)
        & (uv[:, 0] > m * cam.width)
        & (uv[:, 0] < (1 - m) * cam.width)
        & (uv[:, 1] > m * cam.height)
        & (uv[:, 1] < (1 - m) * cam.height)
    )
    return int(ok.sum())


def sample_cameras(
    kind: str,
    target: np.ndarray,
    support_z: float,
    boxes: list[Box3D],
    rng: np.random.Generator,
    cfg: dict[str, Any],
    n_views: int,
    room_half: np.ndarray | None = None,
    centres: np.ndarray | None = None,
    candidates: int = 8,
) -> list[Camera]:
    """`n_views` cameras looking at `target`; eyes outside every box in `boxes` (objects, furniture).

    For each view, `candidates` poses are drawn and the one that shows most object centres wins
    (first one on ties), so close-up views still frame the objects rather than empty table.
    """
    W, H = int(cfg.get("width", 640)), int(cfg.get("height", 480))
    cams: list[Camera] = []
    az0 = rng.uniform(-np.pi, np.pi) if kind == "tabletop" else rng.uniform(-np.pi / 2 - 0.5, -np.pi / 2 + 0.5)
    spread = np.deg2rad(float(cfg.get("view_spread_deg", 70)))
    lo_f, hi_f = cfg.get("fovy_deg", (45.0, 60.0))
    pitch_rng = tuple(float(x) for x in cfg.get("pitch_deg", (30.0, 60.0)))
    height_rng = tuple(float(x) for x in cfg.get("camera_height", (0.3, 0.8)))
    eye_rng = tuple(float(x) for x in cfg.get("room_eye_height", (1.2, 1.8)))
    for v in range(n_views):
        best, best_score, valid = None, -1, 0
        for _ in range(5 * candidates):
            fovy = rng.uniform(lo_f, hi_f)
            pitch = np.deg2rad(rng.uniform(*pitch_rng))
            eye_z = support_z + rng.uniform(*height_rng) if kind == "tabletop" else rng.uniform(*eye_rng)
            az = az0 + (v * spread + rng.normal(0, 0.15) if v else rng.normal(0, 0.1))
            aim = target + np.r_[rng.normal(0, 0.06, 2), 0.0]
            if eye_z - aim[2] <= 0.05:
                continue
            horiz = (eye_z - aim[2]) / np.tan(pitch)
            eye = np.array([aim[0] + horiz * np.cos(az), aim[1] + horiz * np.sin(az), eye_z])
            if room_half is not None and kind == "room" and (np.abs(eye[:2]) > room_half - 0.15).any():
                continue
            if _blocked(eye, boxes):
                continue
            fx, fy, cx, cy = intrinsics(W, H, fovy)
            cam = Camera(W, H, fx, fy, cx, cy, look_at(eye, aim), True)
            sc = _score(cam, centres) if centres is not None and len(centres) else 0
            if sc > best_score:
                best, best_score = cam, sc
            valid += 1
            if valid >= candidates:
                break
        if best is not None:
            cams.append(best)
    return cams
