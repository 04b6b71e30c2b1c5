"""The preview's independent checks of an answer against the stored scene, and the lookups they share with
the overlay drawing (which frame an answer refers to, its free-space region, visual-choice marks)."""

from __future__ import annotations

from typing import Any

import numpy as np

from refspatial_gen.core.mask import denormalise_point
from refspatial_gen.core.model import Frame, FreeSpaceRegion, QAPair, Sample, SceneGraph
from refspatial_gen.run import draw


def answer_points(struct: dict[str, Any]) -> list[tuple[float, float]]:
    """Normalised (x, y) answer points of an `answer_struct` (`points` list and/or a single `point`)."""
    pts = list(struct.get("points") or [])
    if struct.get("point") is not None:
        pts.append(struct["point"])
    out = []
    for p in pts:
        if isinstance(p, (list, tuple)) and len(p) == 2:
            out.append((float(p[0]), float(p[1])))
    return out


def answer_frame_of(sample: Sample, qa: QAPair) -> Frame:
    """The frame the answer's points refer to: `answer_struct.frame_id`, else the question's first frame."""
    want = qa.answer_struct.get("frame_id") or (qa.frame_ids[0] if qa.frame_ids else None)
    for f in sample.frames:
        if want is None or f.frame_id == want:
            return f
    raise KeyError(f"sample {sample.sample_id}: QA {qa.qa_id} refers to frame {want!r}, not in the sample")


def question_frames(sample: Sample, qa: QAPair) -> list[Frame]:
    """The frames a question is about, in the order the question names them ("the first image" is
    `qa.frame_ids[0]`), which need not be the order the sample stores them in."""
    by_id = {f.frame_id: f for f in sample.frames}
    return [by_id[fid] for fid in qa.frame_ids if fid in by_id]


def graph_for(sample: Sample, frame: Frame) -> SceneGraph | None:
    for g in sample.graphs:
        if g.frame_id == frame.frame_id:
            return g
    return None


def region_of_answer(struct: dict[str, Any], graph: SceneGraph | None) -> FreeSpaceRegion | None:
    """The free-space region a placement answer refers to: stored in the struct, or the graph's region
    whose representative point is the answer point."""
    reg = struct.get("region")
    if isinstance(reg, dict) and "polygon_xy" in reg and "z" in reg:
        return FreeSpaceRegion.from_json(
            {"surface_id": "", "kind": "", "anchors": [], "area": 0.0, "point_world": [0, 0, 0], "point": [0, 0], **reg}
        )
    if graph is None:
        return None
    pts = answer_points(struct)
    for r in graph.free_space:
        if any(abs(r.point[0] - x) < 5e-4 and abs(r.point[1] - y) < 5e-4 for x, y in pts):
            return r
    return None


def _inside_polygon(uv: np.ndarray, x: float, y: float) -> bool:
    import cv2

    return cv2.pointPolygonTest(np.asarray(uv, np.float32).reshape(-1, 1, 2), (float(x), float(y)), False) >= 0


def is_placement(qa: QAPair) -> bool:
    return qa.answer_struct.get("kind") == "region" or qa.family == "placement"


def answer_marks(struct: dict[str, Any]) -> list[dict[str, Any]]:
    """Visual-choice marks (`answer_struct.marks`) and option records carrying a point or a box."""
    out = []
    for i, m in enumerate(
        list(struct.get("marks") or []) + [o for o in struct.get("options") or [] if isinstance(o, dict)]
    ):
        if isinstance(m, dict):
            out.append({**m, "label": str(m.get("label") or m.get("letter") or chr(ord("A") + i))})
    return out


def _mask_of(frame: Frame, oid: Any) -> np.ndarray | None:
    try:
        obj = frame.object(int(oid))
    except (KeyError, TypeError, ValueError):
        return None
    return None if obj.mask is None else obj.mask.decode()


def point_checks(sample: Sample, qa: QAPair) -> list[tuple[str, bool]]:
    """Human-readable checks of the answer against the stored scene, re-done here independently.

    - an object point (`kind: points`) must denormalise to a pixel inside a target's visible mask
      (`answer_struct.object_ids`, else `QAPair.targets`): the rule the generators follow;
    - a placement point (`kind: region`) must fall inside its free-space region's projection;
    - a visual-choice mark must sit on its object's mask, and the correct letter must name a target.
    Returns (text, passed) per check.
    """
    frame = answer_frame_of(sample, qa)
    W, H = frame.camera.width, frame.camera.height
    struct = qa.answer_struct
    out: list[tuple[str, bool]] = []
    if is_placement(qa):
        region = region_of_answer(struct, graph_for(sample, frame))
        region_uv = None if region is None else draw.project_polygon(frame.camera, region.polygon_xy, region.z)
        for k, (x, y) in enumerate(answer_points(struct), 1):
            px, py = denormalise_point(x, y, W, H)
            head = f"point {k} ({x:.3f}, {y:.3f}) -> pixel ({px}, {py})"
            if region_uv is None:
                out.append((f"{head}; free-space region: NOT FOUND", False))
            else:
                inside = _inside_polygon(region_uv, px + 0.5, py + 0.5)
                out.append((f"{head}; in free-space region: " + ("yes" if inside else "NO"), inside))
        return out
    ids = struct.get("object_ids") or qa.targets
    masks = [(int(oid), m) for oid in ids if (m := _mask_of(frame, oid)) is not None]
    for k, (x, y) in enumerate(answer_points(struct), 1):
        px, py = denormalise_point(x, y, W, H)
        head = f"point {k} ({x:.3f}, {y:.3f}) -> pixel ({px}, {py})"
        if not masks:
            out.append((f"{head}; no target mask to check", True))
            continue
        hit = [oid for oid, m in masks if m[py, px]]
        out.append((f"{head}; in target mask #{hit[0]}: yes" if hit else f"{head}; in a target mask: NO", bool(hit)))
    letter = struct.get("letter")
    for m in answer_marks(struct):
        view = int(m.get("view", 0) or 0)
        f = sample.frames[view] if 0 <= view < len(sample.frames) else None
        oid = m.get("object_id")
        if f is None or oid is None or not isinstance(m.get("point"), (list, tuple)):
            continue
        mask = _mask_of(f, oid)
        px, py = denormalise_point(float(m["point"][0]), float(m["point"][1]), f.camera.width, f.camera.height)
        ok = mask is not None and bool(mask[py, px])
        text = f"mark ({m['label']}) #{oid}: point in its mask: {'yes' if ok else 'NO'}"
        if m["label"] == letter and qa.targets:
            is_target = int(oid) in [int(t) for t in qa.targets]
            text += f"; correct mark is the target: {'yes' if is_target else 'NO'}"
            ok = ok and is_target
        out.append((text, ok))
    return out
