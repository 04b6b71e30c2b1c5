"""verify's own re-check of look-alike stand-ins (the generator's rule: truth/lookalikes.py, run/pipeline.py).

Why its own code: "the storage box" is only unique, and "the leftmost storage box" only true, when the
frame's basket counts as a possible storage box; verify resolves phrases with and without the faint objects
of the frame as stored (qa/verify_truth.py), so a shard missing a stand-in would pass unseen. From the stored
frame alone, for every category a pair names (its named objects' categories) and every other object the
table (truth/data/lookalikes.yaml) says looks like one, the frame must hold a stand-in of that category with
the object's mask and box and no visibility (visible fraction 0). Skipped when the recorded floor
(graph.meta["truth_floor"]) has `lookalike_stand_ins` 0 or lacks it (written before the rule).
"""

from __future__ import annotations

from typing import Any

import numpy as np

from refspatial_gen.core.model import Frame, QAPair, SceneGraph
from refspatial_gen.qa.verify_truth import named_objects
from refspatial_gen.truth.labels import normalise
from refspatial_gen.truth.lookalikes import lookalikes


def _same_thing(a: Any, b: Any) -> bool:
    """Same mask (run lengths), same box (centre and size)."""
    ma = None if a.mask is None else (a.mask.height, a.mask.width, list(a.mask.counts))
    mb = None if b.mask is None else (b.mask.height, b.mask.width, list(b.mask.counts))
    return ma == mb and np.allclose(a.box.center, b.box.center) and np.allclose(a.box.size, b.box.size)


def check_lookalikes(qa: QAPair, frames: dict[str, Frame], graphs: dict[str, SceneGraph]) -> list[str]:
    """Look-alike stand-ins the pair's frame should store and does not (empty when it passes)."""
    if qa.family == "point_depth" or not qa.frame_ids:
        return []
    out: list[str] = []
    for fid in qa.frame_ids:
        floor = graphs[fid].meta.get("truth_floor")
        if not isinstance(floor, dict) or not floor.get("lookalike_stand_ins"):
            continue
        frame = frames[fid]
        objs = {o.id: o for o in frame.objects}
        asked = {normalise(objs[i].category) for i in named_objects(qa) if i in objs}
        faint = [o for o in frame.objects if float(o.visible_fraction) == 0.0]
        for o in frame.objects:
            if (o.provenance or {}).get("distractor_only"):
                continue
            for cat in sorted(asked & set(lookalikes(o.category)) - {normalise(o.category)}):
                if not any(normalise(s.category) == cat and _same_thing(s, o) for s in faint):
                    out.append(f"object {o.id} ({o.category}) looks like a {cat} but the frame has no such stand-in")
    return out
