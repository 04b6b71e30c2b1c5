"""One preview overlay: the question's frames with answer points, target boxes, free-space regions, marks
and trace positions drawn where the geometry says, and the QA pair's text underneath (run/preview.py)."""

from __future__ import annotations

import json
from typing import Any

import numpy as np

from refspatial_gen.core.model import Frame, QAPair, Sample
from refspatial_gen.run import draw
from refspatial_gen.run.preview_checks import (
    answer_frame_of,
    answer_marks,
    answer_points,
    graph_for,
    is_placement,
    point_checks,
    question_frames,
    region_of_answer,
)


def _draw_frame(sample: Sample, qa: QAPair, frame: Frame, answer_frame: bool) -> tuple[np.ndarray, set[str]]:
    """One frame with its overlays; returns the image and the legend keys used."""
    ov = draw.Overlay.from_rgb(frame.rgb)
    cam = frame.camera
    W, H = cam.width, cam.height
    used: set[str] = set()
    struct = qa.answer_struct
    placement = is_placement(qa)
    graph = graph_for(sample, frame)
    if placement:  # free space matters (and is readable) only where the question is about it
        region = region_of_answer(struct, graph) if answer_frame else None
        seen: dict[float, np.ndarray] = {}

        def visible(z: float) -> np.ndarray:
            if z not in seen:
                seen[z] = draw.plane_visibility(cam, frame.depth, z)
            return seen[z]

        for r in graph.free_space if graph is not None else []:
            uv = draw.project_polygon(cam, r.polygon_xy, r.z)
            if uv is not None and (region is None or r is not region):
                ov.polygon(
                    uv, draw.FREE_SPACE, fill_alpha=0, width=1, visible=visible(float(r.z))
                )  # outlines: regions overlap
                used.add("free")
        if region is not None:
            uv = draw.project_polygon(cam, region.polygon_xy, region.z)
            if uv is not None:
                ov.polygon(uv, draw.ANSWER_REGION, fill_alpha=90, width=3, visible=visible(float(region.z)))
                used.add("region")
    if answer_frame:
        for oid in qa.targets:
            try:
                obj = frame.object(int(oid))
            except KeyError:
                continue
            role = "anchor" if placement else "target"  # a placement answer is free space near its anchors
            ov.segments(draw.project_box_edges(cam, obj.box), draw.TARGET_3D, width=2)
            used.add(f"{role}3d")
            if obj.bbox2d is not None:
                ov.rect(
                    obj.bbox2d,
                    draw.TARGET_2D,
                    width=2,
                    label=f"{'anchor ' if placement else ''}#{obj.id} {obj.category}",
                )
                used.add(f"{role}2d")
    view = next((i for i, f in enumerate(sample.frames) if f is frame), -1)
    for m in answer_marks(struct):
        if int(m.get("view", 0) or 0) != view:
            continue
        correct = m["label"] == struct.get("letter")
        color, width = (draw.ANSWER, 4) if correct else (draw.OPTION, 2)
        box = m.get("box") or m.get("bbox2d")
        if isinstance(box, (list, tuple)) and len(box) == 4:
            ov.rect(box, color, width=width, label=f"({m['label']})", label_below=True)
        elif isinstance(m.get("point"), (list, tuple)) and len(m["point"]) == 2:
            ov.point(float(m["point"][0]) * W, float(m["point"][1]) * H, color, f"({m['label']})", radius=6)
        else:
            continue
        used.add("answer_mark" if correct else "option")
    if answer_frame:
        pts = answer_points(struct)
        for k, ks in enumerate(qa.key_steps, 1):
            if ks.type != "Position" or len(ks.value) != 2:
                continue
            if any(abs(ks.value[0] - x) * W < 1.5 and abs(ks.value[1] - y) * H < 1.5 for x, y in pts):
                continue  # the answer marker is drawn there
            ov.point(ks.value[0] * W, ks.value[1] * H, draw.KEY_STEP, f"s{k}", radius=9, hollow=True)
            used.add("step")
        for k, (x, y) in enumerate(pts, 1):
            ov.point(x * W, y * H, draw.ANSWER, f"A{k}" if len(pts) > 1 else "A")
            used.add("answer")
    return ov.rgb(), used


_LEGEND = [
    ("answer", draw.ANSWER, "answer point"),
    ("answer_mark", draw.ANSWER, "correct mark"),
    ("option", draw.OPTION, "other marks"),
    ("region", draw.ANSWER_REGION, "answer region"),
    ("free", draw.FREE_SPACE, "free space"),
    ("target2d", draw.TARGET_2D, "target 2D box"),
    ("target3d", draw.TARGET_3D, "target 3D box"),
    ("anchor2d", draw.TARGET_2D, "anchor 2D box"),
    ("anchor3d", draw.TARGET_3D, "anchor 3D box"),
    ("step", draw.KEY_STEP, "trace position"),
]


def _struct_text(struct: dict[str, Any]) -> str:
    s = json.dumps(struct, sort_keys=True, ensure_ascii=False)
    return s if len(s) <= 400 else s[:397] + "..."


def render_preview(sample: Sample, qa_index: int) -> np.ndarray:
    """The overlay image (uint8 RGB) for `sample.qa[qa_index]`: frames side by side, text underneath."""
    qa = sample.qa[qa_index]
    ans_frame = answer_frame_of(sample, qa)
    frames = question_frames(sample, qa) or [ans_frame]
    tiles, used = [], set()
    for k, f in enumerate(frames, 1):
        img, u = _draw_frame(sample, qa, f, f is ans_frame)
        tiles.append(draw.caption_above(img, f"image {k}: {f.frame_id}") if len(frames) > 1 else img)
        used |= u
    top = draw.hstack(tiles)
    width = max(top.shape[1], 640)
    rels = ", ".join(qa.relations) or "-"
    blocks: list[tuple[str, str, draw.RGB]] = [
        (
            f"{qa.family} · {qa.template} · {qa.steps} step{'s' if qa.steps != 1 else ''} · relations: {rels}",
            "bold",
            (150, 200, 255),
        ),
        (f"Q: {qa.question}", "regular", (240, 240, 240)),
        (f"A: {qa.answer}", "bold", (255, 140, 140)),
        (f"answer_struct: {_struct_text(qa.answer_struct)}", "mono", (180, 180, 180)),
    ]
    if qa.trace:
        blocks.append((f"trace:\n{qa.trace}", "mono", (255, 200, 120)))
    if qa.key_steps:
        ks = "\n".join(
            f"s{k} [{s.type}] {s.phrase}: {', '.join(f'{v:.3f}' for v in s.value)}"
            for k, s in enumerate(qa.key_steps, 1)
        )
        blocks.append((f"key steps:\n{ks}", "mono", (255, 200, 120)))
    checks = point_checks(sample, qa)
    if checks:
        bad = not all(ok for _, ok in checks)
        blocks.append(
            ("preview check:\n" + "\n".join(t for t, _ in checks), "mono", (255, 90, 90) if bad else (140, 230, 140))
        )
    if qa.checks:
        blocks.append(("generator checks passed: " + ", ".join(qa.checks), "regular", (170, 170, 170)))
    W, H = qa.image_size
    blocks.append(
        (
            f"sample {sample.sample_id} · qa {qa.qa_id} · frames {', '.join(f.frame_id for f in frames)}"
            f" · image {W}x{H}",
            "regular",
            (140, 140, 140),
        )
    )
    leg = draw.legend([(c, label) for key, c, label in _LEGEND if key in used], width) if used else None
    panel = draw.text_panel(blocks, width)
    out = draw.vstack(top, leg) if leg is not None else top
    return draw.vstack(out, panel)
