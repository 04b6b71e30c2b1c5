"""verify's own re-check of the photo truth rules (the generator's filter is qa/faint_photo.py).

From the stored frame alone: which objects have no trusted 3D position (the mask decoded and measured against
the image border and the recorded `foot_border_margin`, the stored contact notes, the categories that never
meet the floor); the recorded flag must agree. Then every step of the pair's program, with the objects it
reads (its arguments, the outputs of the steps it refers to) and gives, and every referring phrase:
  - no position or size relation on an object without a trusted position;
  - on an estimated-depth photo, no size relation or size superlative between two objects of one category;
  - no phrase naming an object of a category the reader marked incomplete, no set of such a category;
  - on an estimated-depth photo, no width measurement or wider/thinner comparison (the lifted footprint is
    only the apparent width, squared).
"""

from __future__ import annotations

from typing import Any

import numpy as np

from refspatial_gen.core.model import Frame, QAPair
from refspatial_gen.qa.verify_truth import program_phrases
from refspatial_gen.truth.contact import OFF_GROUND

_POSITION = {"front", "behind", "above_world", "below_world", "close", "far", "depth", "distance", "touching"}
_POSITION |= {"far_from", "next_to", "between", "inside", "outside"}
_SIZE = {"tall", "short", "big", "small", "wide", "thin"}
_FOOTPRINT = {"wide", "thin", "width"}
_EDGE = 2  # mask pixels in the outer 3 rows/columns reach the border (graph/visibility.BORDER_PX)


def unplaced(frame: Frame) -> dict[int, str]:
    """Objects whose lifted position rests on an unseen foot, recomputed from the stored frame."""
    margin = frame.meta.get("foot_border_margin")
    if margin is None:  # not a geometric-depth photo
        return {}
    H, W = frame.camera.height, frame.camera.width
    out: dict[int, str] = {}
    for o in frame.objects:
        prov = o.provenance or {}
        m = o.mask.decode() if o.mask is not None else np.zeros((H, W), bool)
        ys, xs = np.nonzero(m)
        contact = str(prov.get("contact", ""))
        if len(xs) and (
            xs.min() <= _EDGE or ys.min() <= _EDGE or xs.max() >= W - 1 - _EDGE or ys.max() >= H - 1 - _EDGE
        ):
            out[o.id] = "mask reaches the image border"
        elif prov.get("behind") or contact.startswith("behind"):
            out[o.id] = "stands behind an occluder"
        elif (len(ys) and ys.max() >= H * (1 - float(margin)) - 1) or prov.get("contact_truncated"):
            out[o.id] = "foot at the bottom edge"
        elif o.category in OFF_GROUND and contact == "ground":
            out[o.id] = f"a {o.category} placed on the ground"
    return out


def _objects(x: Any, outs: dict[str, Any], everything: list[int]) -> list[int]:
    if isinstance(x, bool) or x is None:
        return []
    if isinstance(x, int):
        return [x]
    if isinstance(x, str):
        return list(everything) if x == "all" else []
    if isinstance(x, list):
        return [i for v in x for i in _objects(v, outs, everything)]
    if isinstance(x, dict):
        if "step" in x and len(x) == 1:
            return _objects(outs.get(str(x["step"])), outs, everything)
        keys = ("object", "options", "anchor", "a", "b", "c", "of", "to", "in", "object_ids")
        return [i for k in keys if k in x for i in _objects(x[k], outs, everything)]
    return []


def check_photo(qa: QAPair, frame: Frame) -> list[str]:
    """Reasons the pair breaks a photo truth rule (empty when it passes or the frame is not a photo)."""
    if frame.source != "image":
        return []
    cat = {o.id: o.category for o in frame.objects}
    bad = unplaced(frame)
    out = [
        f"object {o.id} ({o.category}): position flag {(o.provenance or {}).get('position_unseen')!r} disagrees "
        f"with the frame ({bad.get(o.id)!r})"
        for o in frame.objects
        if "foot_border_margin" in frame.meta and bool((o.provenance or {}).get("position_unseen")) != (o.id in bad)
    ]
    scale = frame.meta.get("metric_scale")
    estimated = isinstance(scale, dict) and scale.get("source") != "measured"
    partial = set(frame.meta.get("incomplete_categories") or {})
    outs: dict[str, Any] = {}
    for st in qa.program:
        a = st.get("args") or {}
        rel = a.get("relation") or a.get("quantity") or ("between" if st.get("op") == "between" else None)
        ids = set(_objects(a, outs, sorted(cat))) | set(_objects(st.get("out"), outs, sorted(cat)))
        outs[str(st.get("as"))] = st.get("out")
        hit = sorted(ids & set(bad))
        if (rel in _POSITION or rel in _SIZE) and hit:
            out.append(f"step {st.get('as')} ({rel}) involves object {hit[0]}: {bad[hit[0]]}")
        named = [cat[i] for i in sorted(ids) if i in cat]
        if estimated and rel in _FOOTPRINT:
            out.append(f"step {st.get('as')} ({rel}) rests on a photo's unmeasured footprint")
        if estimated and rel in _SIZE and len(set(named)) < len(named):
            out.append(f"step {st.get('as')} compares sizes within one category on a photo")
        if st.get("op") == "filter" and partial & set(named):
            out.append(
                f"step {st.get('as')} takes every {sorted(partial & set(named))[0]}: its annotation is incomplete"
            )
    out += _phrase_problems(qa, frame, cat, bad, estimated, partial)
    return out


def _phrase_problems(
    qa: QAPair, frame: Frame, cat: dict[int, str], bad: dict[int, str], estimated: bool, partial: set[str]
) -> list[str]:
    out = []
    for phrase, oid in program_phrases(qa):
        c = cat.get(oid)
        words = phrase.split()
        if c in partial:
            out.append(f"phrase {phrase!r} names a {c}: its annotation is incomplete")
        if estimated and {"tallest", "shortest", "biggest", "smallest"} & set(words):
            out.append(f"phrase {phrase!r} ranks {c}s by size on a photo")
        if {"nearest", "farthest", "closest"} & set(words):
            from refspatial_gen.graph.resolve import resolve_phrase

            group = {i for i, k in cat.items() if k == c}
            for sep in (" closest to ", " farthest from "):
                if sep in phrase:
                    group |= set(resolve_phrase(phrase.split(sep, 1)[1], frame))
            hit = sorted(group & set(bad))
            if hit:
                out.append(f"phrase {phrase!r} ranks by 3D position over object {hit[0]}: {bad[hit[0]]}")
    return out
