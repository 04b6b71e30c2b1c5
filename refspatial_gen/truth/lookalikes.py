"""Objects a person could take for one another: faint look-alike stand-ins (truth/data/lookalikes.yaml).

Why (audit-pre): uniqueness, superlatives, ordinals and counts were decided over the objects of the named
category only, but a viewer decides over everything that looks like one. A beige basket holding a banana
was counted as a storage box by the reader of "among the storage boxes nearer than the blue one, the one
farthest from the white box" (sim:000018/v1:03); "how wide is the storage box?" had two other open boxes in
view (sim:000012/v0:04); "the glass" was a tiny blob on a far shelf while a prominent wine glass stood on the
table (sim:000001/v1:08); a gray tumbler filed as a cup looked like "the gray glass" (ycb sim:000020/v1:04).

The rule: for every object of the frame (not a distractor itself) whose category has look-alikes that the
frame also names, one faint *stand-in* per such look-alike category is added: the object's mask, box, 2D box
and colour, `visible_fraction` 0 and `provenance["distractor_only"] = "lookalike"` (`stand_in_for`: the
object). The visibility floor (graph/visibility.py) gives a stand-in no phrase and no answer point, so it is
never named, but it counts: "the storage box" is not unique beside a basket (the phrase must single the box
out over the stand-ins too: "the red storage box"), and qa/faint.py withholds every pair whose answer a
stand-in could change ("the leftmost storage box", "how many glasses"). A referent far smaller on screen than
a visible look-alike (the tiny glass, the big wine glass) is thus never named by the bare category.

Stand-ins are added to the frame before it is stored (run/pipeline.py), so the shard keeps them and verify
resolves phrases over them as stored; qa/verify_lookalike.py re-derives from the stored frame which stand-ins
every named object needs and fails a pair whose frame lacks one. Recipe: `graph: truth: lookalike_stand_ins`
(1 on, 0 off). Counted in `frame.meta["truth"]["lookalike_stand_ins"]`; withheld pairs by qa/faint.py's reasons.
"""

from __future__ import annotations

from dataclasses import replace
from functools import lru_cache
from pathlib import Path
from typing import Any

from refspatial_gen.core.model import Frame, ObjectInstance
from refspatial_gen.truth.labels import normalise

DATA = Path(__file__).parent / "data"
LOOKALIKE = "lookalike"  # provenance["distractor_only"] of a stand-in
COUNT = "lookalike_stand_ins"  # frame.meta["truth"] key
STAND_IN_BASE = 200000  # stand-in ids start at a multiple of this above every object id of the frame


@lru_cache(maxsize=1)
def _groups() -> dict[str, frozenset[str]]:
    """category -> the categories it looks like (the union of the other members of its groups)."""
    import yaml

    with open(DATA / "lookalikes.yaml", encoding="utf-8") as f:
        raw = yaml.safe_load(f) or {}
    out: dict[str, set[str]] = {}
    for name, g in (raw.get("groups") or {}).items():
        members = [normalise(m) for m in (g or {}).get("members") or []]
        if len(set(members)) < 2 or not str((g or {}).get("why") or "").strip():
            raise ValueError(f"lookalikes.yaml: group {name}: needs two or more members and a why, got {g!r}")
        for m in members:
            out.setdefault(m, set()).update(x for x in members if x != m)
    return {k: frozenset(v) for k, v in out.items()}


def lookalikes(category: str) -> frozenset[str]:
    """The categories a person could take a `category` for (normalised; empty when none)."""
    return _groups().get(normalise(category), frozenset())


def is_stand_in(o: ObjectInstance) -> bool:
    return o.provenance.get("distractor_only") == LOOKALIKE


def needed(objects: list[ObjectInstance]) -> list[tuple[int, str]]:
    """(object id, category) of every stand-in the objects call for: per object that is not a distractor,
    each look-alike category the frame's other named objects have (nothing else can be named in a question)."""
    real = [o for o in objects if not o.provenance.get("distractor_only")]
    named: dict[str, str] = {}  # normalised -> the category as the frame spells it
    for o in real:
        named.setdefault(normalise(o.category), o.category)
    out = []
    for o in sorted(real, key=lambda o: o.id):
        own = normalise(o.category)
        for c in sorted(lookalikes(own)):
            if c in named and c != own:
                out.append((int(o.id), named[c]))
    return out


def stand_in(o: ObjectInstance, category: str, new_id: int) -> ObjectInstance:
    """A faint copy of `o` under `category`: same mask, boxes and colour; no front, a distractor only."""
    prov: dict[str, Any] = dict(o.provenance)
    prov.update({"distractor_only": LOOKALIKE, "stand_in_for": int(o.id), "lookalike_of": o.category})
    return replace(
        o, id=new_id, category=category, visible_fraction=0.0, name=None, description=None,
        front=None, front_phrase=None, provenance=prov,
    )  # fmt: skip


def add_lookalike_stand_ins(frame: Frame) -> Frame:
    """The frame with its look-alike stand-ins appended (ids from a multiple of STAND_IN_BASE above every id)
    and their number added to frame.meta["truth"]; the frame itself when none is needed or it has them."""
    if any(is_stand_in(o) for o in frame.objects):
        return frame
    want = needed(frame.objects)
    if not want:
        return frame
    by_id = {o.id: o for o in frame.objects}
    top = max(o.id for o in frame.objects)
    base = STAND_IN_BASE * (1 + top // STAND_IN_BASE)
    extra = [stand_in(by_id[i], c, base + k) for k, (i, c) in enumerate(want)]
    meta = dict(frame.meta or {})
    truth = dict(meta.get("truth") or {})
    truth[COUNT] = truth.get(COUNT, 0) + len(extra)
    meta["truth"] = dict(sorted(truth.items()))
    return replace(frame, objects=list(frame.objects) + extra, meta=meta)
