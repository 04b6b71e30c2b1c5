"""verify's own re-check of the truth floors (not the generator's filter: graph/visibility.py, qa/faint.py).

From what a shard stores, for every object a QA pair names (program arguments and outputs, targets, options,
marks, key steps):
  - visible pixels counted from its decoded mask, the source's visible fraction, and the share of its 3D box
    inside the image (a 5x5x5 lattice on the box's faces and inside, projected through the camera) against the
    floor the graph recorded (graph.meta["truth_floor"], the recipe's `graph: truth:`);
  - every referring phrase resolved by the independent resolver on the frame as stored and on the frame
    without the objects below the floor: a phrase that names the object in one and not the other fails;
  - for a metric value or a size comparison: the stored box against its category's size range
    (truth/sizes.py) and the frame's metric scale.
"""

from __future__ import annotations

from dataclasses import replace
from typing import Any

import numpy as np

from refspatial_gen.core.model import Frame, QAPair, SceneGraph
from refspatial_gen.truth.sizes import check_size

METRIC_RELATIONS = ("distance", "depth", "tall", "short", "big", "small", "wide", "thin")
IN_VIEW_TOL = 0.07  # lattice error bound of the generator's (<= 1/(2*12)) plus this one's (<= 1/(2*20))
_LATTICE = 20


def named_objects(qa: QAPair) -> set[int]:
    """Every object id the pair's record names (ints under object-valued keys, outputs of object steps)."""
    out: set[int] = set(int(t) for t in qa.targets)

    def walk(x: Any, key: str = "") -> None:
        if isinstance(x, dict):
            for k, v in x.items():
                walk(v, k)
        elif isinstance(x, list):
            for v in x:
                walk(v, key)
        elif isinstance(x, int) and not isinstance(x, bool) and key in _OBJECT_KEYS:
            out.add(int(x))

    for st in qa.program:
        walk(st.get("args") or {})
        o = st.get("out")
        if isinstance(o, int) and not isinstance(o, bool):  # a superlative's / ordinal's object
            out.add(int(o))
        elif isinstance(o, dict):  # a located object, a choice's options
            walk(o)
        elif st.get("op") == "mark" and isinstance(o, list):  # the marked objects
            walk(o, "object_ids")
    s = qa.answer_struct or {}
    walk({k: v for k, v in s.items() if k in ("object_ids", "option_ids", "marks", "object_id")})
    return out


_OBJECT_KEYS = {"object", "object_ids", "option_ids", "object_id", "options"}


def _box_in_view(frame: Frame, box: Any) -> float:
    t = (np.arange(_LATTICE) + 0.5) / _LATTICE - 0.5  # cell centres: an unbiased share (end points are not)
    g = np.stack(np.meshgrid(t, t, t, indexing="ij"), -1).reshape(-1, 3) * np.asarray(box.size, float)
    world = np.asarray(box.center, float) + g @ np.asarray(box.rotation, float).T
    uv, z = frame.camera.project(world)
    cam = frame.camera
    ok = (z > 1e-3) & (uv[:, 0] >= 0) & (uv[:, 0] < cam.width) & (uv[:, 1] >= 0) & (uv[:, 1] < cam.height)
    return float(ok.mean())


def below_floor(frame: Frame, floor: dict[str, Any]) -> dict[int, str]:
    """Objects of the stored frame under the recorded floor, with why (recomputed from masks and boxes)."""
    out: dict[int, str] = {}
    for o in frame.objects:
        px = 0 if o.mask is None else int(o.mask.decode().sum())
        if px < int(floor.get("min_visible_px", 0)):
            out[o.id] = f"{px} visible pixels < {floor['min_visible_px']}"
        elif float(o.visible_fraction) < float(floor.get("min_visible_fraction", 0.0)):
            out[o.id] = f"visible fraction {o.visible_fraction:.3f} < {floor['min_visible_fraction']}"
        elif _box_in_view(frame, o.box) < float(floor.get("min_in_view_fraction", 0.0)) - IN_VIEW_TOL:
            out[o.id] = f"{_box_in_view(frame, o.box):.2f} of its box in view < {floor['min_in_view_fraction']}"
    return out


def _phrases(qa: QAPair) -> list[tuple[str, int]]:
    out = []

    def walk(x: Any) -> None:
        if isinstance(x, dict):
            if "phrase" in x and isinstance(x.get("object"), int):
                out.append((str(x["phrase"]), int(x["object"])))
            for v in x.values():
                walk(v)
        elif isinstance(x, list):
            for v in x:
                walk(v)

    for st in qa.program:
        walk(st.get("args") or {})
    return sorted(set(out))


def _size(box: Any) -> tuple[float, float, float]:
    """(larger, smaller horizontal extent, height) of a stored box, from its rotated corners (z up)."""
    c = np.asarray(box.corners(), float)
    R = np.asarray(box.rotation, float)
    s = np.asarray(box.size, float)
    h = float(c[:, 2].max() - c[:, 2].min())
    horiz = sorted(float(np.hypot(*(R[:2, k] * s[k]))) for k in range(3) if abs(R[2, k]) < 0.99)
    w = horiz[-1] if horiz else float(max(s))
    return w, w, h


def check_truth(qa: QAPair, frames: dict[str, Frame], graphs: dict[str, SceneGraph]) -> list[str]:
    """Reasons the pair breaks a truth floor (empty when it passes)."""
    if qa.family == "point_depth" or not qa.frame_ids:
        return []
    out: list[str] = []
    fid = qa.frame_ids[0]
    frame, graph = frames[fid], graphs[fid]
    floor = graph.meta.get("truth_floor")
    if not isinstance(floor, dict):
        return []  # written before the floors existed
    objs = {o.id: o for o in frame.objects}
    named = {i for i in named_objects(qa) if i in objs}
    low = below_floor(frame, floor)
    for i in sorted(named & set(low)):
        out.append(f"names object {i} ({objs[i].category}) below the visibility floor: {low[i]}")
    if low:
        out += _phrase_changes(qa, frame, set(low))
    if not set(METRIC_RELATIONS).isdisjoint(qa.relations):
        out += _metric(qa, frame, named, objs, float(floor.get("size_tolerance", 0.0)))
    return out


def _phrase_changes(qa: QAPair, frame: Frame, low: set[int]) -> list[str]:
    from refspatial_gen.graph.resolve import resolve_phrase

    seen = replace(frame, objects=[o for o in frame.objects if o.id not in low])
    out = []
    for phrase, oid in _phrases(qa):
        full = resolve_phrase(phrase, frame)
        if list(full) != [oid]:
            continue  # the graph-based phrase check (verify.py) judges uniqueness
        if list(resolve_phrase(phrase, seen)) != [oid]:
            out.append(f"phrase {phrase!r} names object {oid} only when objects below the floor {sorted(low)} count")
    return out


def _metric(qa: QAPair, frame: Frame, named: set[int], objs: dict[int, Any], tol: float) -> list[str]:
    scale = frame.meta.get("metric_scale")
    if isinstance(scale, dict) and scale.get("reliable") is False:
        return [
            f"metric or size question ({sorted(set(METRIC_RELATIONS) & set(qa.relations))}) on a frame "
            "whose metric scale is unverified"
        ]
    out = []
    H, W = frame.camera.height, frame.camera.width
    for i in sorted(named):
        o = objs[i]
        if isinstance(scale, dict):  # a photo: the object must be wholly seen (graph/visibility.partly_seen)
            ys, xs = np.nonzero(o.mask.decode()) if o.mask is not None else (np.zeros(0), np.zeros(0))
            if len(xs) and (xs.min() <= 2 or ys.min() <= 2 or xs.max() >= W - 3 or ys.max() >= H - 3):
                out.append(f"metric or size question names object {i} ({o.category}): its mask reaches the border")
                continue
            if (o.provenance or {}).get("behind") or str((o.provenance or {}).get("contact", "")).startswith("behind"):
                out.append(f"metric or size question names object {i} ({o.category}): it stands behind an occluder")
                continue
        why = check_size(
            o.category, _size(o.box), dims=("height", "extent"), tolerance=tol + 0.02, lower_bounds=("extent",)
        )
        if why is not None:
            out.append(f"metric or size question names object {i} ({o.category}): {why}")
    return out
