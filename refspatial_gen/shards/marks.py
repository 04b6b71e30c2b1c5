"""Drawing the marks of visual-choice questions on a copy of an image, at export time.

Why re-draw instead of storing marked images: the shard already holds the image, the boxes and the
masks, so a marked copy is a pure function of stored data; storing it would double the image bytes.

Contract with the QA engine (answer_struct): a QA pair whose image needs marks carries
  answer_struct["marks"] = [{"label": "A", "object_id": 3, "style": "box" | "point", "view": 0}, ...]
("view", the asked frame's position among the sample's frames, defaults to 0; "style" to "box").
Box style draws the object's 2D box (bbox2d) with its label;
point style draws a dot at the object's answer point (its graph node point, else its mask answer pixel).
"""

from __future__ import annotations

import numpy as np

from refspatial_gen.core.mask import RLE, answer_pixel

_PALETTE = [
    (230, 25, 75),
    (60, 180, 75),
    (0, 130, 200),
    (245, 130, 48),
    (145, 30, 180),
    (70, 240, 240),
    (240, 50, 230),
    (210, 245, 60),
]


def marks_of(qa: dict) -> list[dict]:
    marks = (qa.get("answer_struct") or {}).get("marks") or []
    if not isinstance(marks, list):
        raise ValueError(f"QA {qa.get('qa_id')}: answer_struct.marks must be a list")
    return marks


def draw_marks(rgb: np.ndarray, frame_meta: dict, marks: list[dict], graph: dict | None = None) -> np.ndarray:
    """A copy of `rgb` with each mark drawn; raises ValueError for a mark naming an unknown object."""
    import cv2

    img = np.ascontiguousarray(rgb.copy())
    h, w = img.shape[:2]
    objects = {int(o["id"]): o for o in frame_meta["objects"]}
    points = {int(n["object_id"]): n.get("point") for n in (graph or {}).get("nodes", [])}
    scale = max(0.4, min(w, h) / 600.0)
    thick = max(1, int(round(2 * scale)))
    for k, m in enumerate(marks):
        oid = int(m["object_id"])
        if oid not in objects:
            raise ValueError(
                f"mark {m.get('label')!r} names object {oid}, which is not in frame {frame_meta['frame_id']}"
            )
        o = objects[oid]
        colour = _PALETTE[k % len(_PALETTE)]
        label = str(m.get("label", chr(ord("A") + k)))
        if m.get("style", "box") == "point":
            p = points.get(oid)
            if p is not None:
                x, y = int(p[0] * w), int(p[1] * h)
            else:
                px = answer_pixel(RLE.from_json(o["mask"]).decode())
                if px is None:
                    raise ValueError(f"object {oid} has an empty mask: cannot draw a point mark")
                x, y = int(px[0]), int(px[1])
            cv2.circle(img, (x, y), max(3, int(5 * scale)), colour, -1, cv2.LINE_AA)
            cv2.circle(img, (x, y), max(3, int(5 * scale)), (255, 255, 255), 1, cv2.LINE_AA)
            org = (min(w - 12, x + 6), max(12, y - 6))
        else:
            if o.get("bbox2d") is None:
                raise ValueError(f"object {oid} has no bbox2d: cannot draw a box mark")
            x0, y0, x1, y1 = (int(round(v)) for v in o["bbox2d"])
            cv2.rectangle(img, (x0, y0), (x1 - 1, y1 - 1), colour, thick, cv2.LINE_AA)
            org = (max(0, x0 + 2), max(12, y0 - 3) if y0 > 14 else y0 + int(14 * scale))
        cv2.putText(
            img, label, org, cv2.FONT_HERSHEY_SIMPLEX, 0.5 * scale * 1.4, (255, 255, 255), thick + 2, cv2.LINE_AA
        )
        cv2.putText(img, label, org, cv2.FONT_HERSHEY_SIMPLEX, 0.5 * scale * 1.4, colour, thick, cv2.LINE_AA)
    return img


def marked_pngs(raw, qa: dict) -> dict[int, bytes]:
    """{view: PNG bytes} of the marked copies a visual-choice QA pair needs (empty when it has no marks).

    `raw` is a shards.format.RawSample; marks are grouped by their `view` (default 0).
    """
    import cv2

    marks = marks_of(qa)
    if not marks:
        return {}
    graphs = {g["frame_id"]: g for g in raw.graphs_json()}
    by_view: dict[int, list[dict]] = {}
    for m in marks:
        by_view.setdefault(int(m.get("view", 0)), []).append(m)
    out = {}
    for v, ms in sorted(by_view.items()):
        fm = raw.frame_meta(v)
        img = draw_marks(raw.rgb(v), fm, ms, graphs.get(fm["frame_id"]))
        ok, buf = cv2.imencode(".png", np.ascontiguousarray(img[..., ::-1]))
        if not ok:
            raise ValueError("marked image encoding failed")
        out[v] = buf.tobytes()
    return out
