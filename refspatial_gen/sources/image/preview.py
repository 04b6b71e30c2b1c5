"""Preview images of lifted frames: projected 3D box edges, mask outlines and answer points, plus a
top-down (bird's-eye) panel of the boxes. For looking at what the lifting did, not for training."""

from __future__ import annotations

from pathlib import Path

import numpy as np

from refspatial_gen.core.mask import answer_pixel
from refspatial_gen.core.model import Frame

EDGES = [(0, 1), (0, 2), (1, 3), (2, 3), (4, 5), (4, 6), (5, 7), (6, 7), (0, 4), (1, 5), (2, 6), (3, 7)]


def _colour(k: int) -> tuple[int, int, int]:
    rng = np.random.default_rng(k * 7919 + 3)
    c = rng.integers(60, 256, 3)
    return int(c[0]), int(c[1]), int(c[2])


def draw_frame(frame: Frame, extra_boxes: list | None = None, top_view: bool = True) -> np.ndarray:
    """RGB preview (uint8): boxes, masks, answer points; `extra_boxes` (e.g. ground truth) in white."""
    import cv2

    img = frame.rgb.copy()
    cam = frame.camera

    def draw_box(box, col, thick=2):
        uv, z = cam.project(box.corners())
        if np.any(~np.isfinite(uv)) or np.any(z <= 0):
            return
        p = np.round(uv).astype(int)
        for a, b in EDGES:
            cv2.line(img, tuple(p[a]), tuple(p[b]), col, thick, cv2.LINE_AA)

    for o in frame.objects:
        col = _colour(o.id)
        m = o.mask.decode().astype(np.uint8)
        cnts, _ = cv2.findContours(m, cv2.RETR_EXTERNAL, cv2.CHAIN_APPROX_SIMPLE)
        cv2.drawContours(img, cnts, -1, col, 1)
        draw_box(o.box, col)
        pt = answer_pixel(o.mask.decode())
        if pt is not None:
            cv2.circle(img, (int(pt[0]), int(pt[1])), 5, (255, 255, 255), -1)
            cv2.circle(img, (int(pt[0]), int(pt[1])), 3, col, -1)
            cv2.putText(
                img,
                f"{o.id}:{o.category}",
                (int(pt[0]) + 6, int(pt[1]) - 6),
                cv2.FONT_HERSHEY_SIMPLEX,
                0.45,
                (255, 255, 255),
                2,
                cv2.LINE_AA,
            )
            cv2.putText(
                img,
                f"{o.id}:{o.category}",
                (int(pt[0]) + 6, int(pt[1]) - 6),
                cv2.FONT_HERSHEY_SIMPLEX,
                0.45,
                col,
                1,
                cv2.LINE_AA,
            )
    for b in extra_boxes or []:
        draw_box(b, (255, 255, 255), 1)
    if not top_view:
        return img
    return np.concatenate([img, _top_view(frame, img.shape[0], extra_boxes)], axis=1)


def _top_view(frame: Frame, size: int, extra_boxes: list | None) -> np.ndarray:
    import cv2

    canvas = np.full((size, size, 3), 30, np.uint8)
    boxes = [o.box for o in frame.objects] + list(extra_boxes or [])
    pts = np.concatenate([b.corners()[:, :2] for b in boxes] + [frame.camera.position[None, :2]])
    lo, hi = pts.min(axis=0) - 0.3, pts.max(axis=0) + 0.3
    s = (size - 20) / max(hi - lo)

    def px(xy):
        q = (np.asarray(xy) - lo) * s + 10
        return np.stack([q[..., 0], size - q[..., 1]], -1).round().astype(np.int32)

    for i, b in enumerate(boxes):
        col = _colour(frame.objects[i].id) if i < len(frame.objects) else (255, 255, 255)
        cv2.polylines(canvas, [px(b.footprint())], True, col, 2 if i < len(frame.objects) else 1, cv2.LINE_AA)
    c = px(frame.camera.position[:2])
    cv2.circle(canvas, tuple(int(v) for v in c), 5, (0, 255, 255), -1)
    cv2.putText(
        canvas,
        f"top view, {1.0 / s * 100:.1f} cm/px",
        (10, 20),
        cv2.FONT_HERSHEY_SIMPLEX,
        0.45,
        (200, 200, 200),
        1,
        cv2.LINE_AA,
    )
    return canvas


def save_preview(frame: Frame, path: str | Path, extra_boxes: list | None = None) -> Path:
    import cv2

    p = Path(path)
    p.parent.mkdir(parents=True, exist_ok=True)
    cv2.imwrite(str(p), draw_frame(frame, extra_boxes)[..., ::-1])
    return p
