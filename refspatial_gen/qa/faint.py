"""Truth checks on a finished instantiation: the answer must not depend on objects a viewer cannot see, and
metric or size questions need objects (and a frame) whose size the world can vouch for.

Why: the graph (graph/visibility.py) takes the answer point and phrases away from objects below the
visibility floor, so they are never named, marked, offered or pointed at; but they stay in the scene, so
"the second cup from the left", "how many cups" or "the closest" still count them. A viewer may or may not
notice them, so a question is emitted only when it has the same answer either way: the program is re-run
on the scene without the faint objects (every object without an answer point) and every step must agree
(sets up to the faint objects themselves). Each withheld pair is counted by reason (sample.meta["truth"]).

  faint_changes_answer   without the faint objects a step gives another object, number or answer
  faint_no_answer        without the faint objects the program has no answer
  metric_withheld        a distance / depth / size value or a size comparison involves an object whose
                         category has no size range or whose lifted size is implausible, or a frame whose
                         metric scale is unverified (node attribute `metric: false`)
  position_contact_unseen, size_same_category, incomplete_category_claim
                         photos only: qa/faint_photo.py
"""

from __future__ import annotations

from typing import Any

from refspatial_gen.core.model import QAPair, SceneGraph
from refspatial_gen.graph.relations import REGISTRY
from refspatial_gen.qa.faint_photo import photo_withhold
from refspatial_gen.qa.index import Reject, SceneIndex
from refspatial_gen.qa.program import Template
from refspatial_gen.qa.values import Context, NumberValue, OptionValue, PointValue

METRIC_RELATIONS = frozenset({"distance", "depth"}) | frozenset(
    n for n in REGISTRY.names() if REGISTRY[n].group == "sizes"
)
CHANGES, NO_ANSWER, METRIC = "faint_changes_answer", "faint_no_answer", "metric_withheld"


def faint_ids(idx: SceneIndex) -> frozenset[int]:
    """Objects of the frame a viewer may not see: every node without an answer point."""
    hit = idx.__dict__.get("_faint")
    if hit is None:
        hit = idx.__dict__["_faint"] = frozenset(i for i in idx.ids if i not in idx.answer_points)
    return hit


def seen_view(idx: SceneIndex) -> SceneIndex:
    """The frame's index without its faint objects (their nodes and every stored fact naming one)."""
    hit = idx.__dict__.get("_seen_view")
    if hit is None:
        faint = faint_ids(idx)
        g = idx.graph
        facts = [f for f in g.facts if not any(type(a) is int and a in faint for a in f.args)]
        graph = SceneGraph(g.frame_id, [n for n in g.nodes if n.object_id not in faint], facts, g.free_space, g.meta)
        hit = idx.__dict__["_seen_view"] = SceneIndex(idx.frame, graph)
    return hit


def objects_in(v: Any, out: set[int]) -> set[int]:
    """Every object id a step value holds (objects, sets, options, marks, answer points)."""
    if isinstance(v, bool) or v is None:
        return out
    if isinstance(v, int):
        out.add(v)
    elif isinstance(v, (frozenset, tuple, list)):
        for x in v:
            objects_in(x, out)
    elif isinstance(v, PointValue) and v.object_id is not None:
        out.add(v.object_id)
    elif isinstance(v, OptionValue):
        objects_in(v.options, out)
    return out


def binds_flagged(t: Template, env: dict[str, Any], ctx: Context, attribute: str) -> bool:
    """True when an object the instance binds or computes (slots and step values, sets included) has the node
    attribute `attribute` set to False in either view (`metric`, `sized`)."""
    ids: set[int] = set()
    for k, v in env.items():
        if k in t.slots or any(st.name == k for st in t.steps):
            objects_in(v, ids)
    for ix in (ctx.idx, ctx.second):
        if ix is None:
            continue
        for i in sorted(ids):
            n = ix.nodes.get(i)
            if n is not None and n.attributes.get(attribute) is False:
                return True
    return False


def metric_ok(t: Template, env: dict[str, Any], ctx: Context, qa: QAPair) -> bool:
    """False when the pair asks a metric value or a size comparison of an object the graph marks `metric: false`."""
    return METRIC_RELATIONS.isdisjoint(qa.relations) or not binds_flagged(t, env, ctx, "metric")


def _agree(full: Any, alt: Any, faint: frozenset[int]) -> bool:
    if isinstance(full, frozenset) and isinstance(alt, frozenset):
        return full - faint == alt
    if isinstance(full, NumberValue) and isinstance(alt, NumberValue):
        return round(full.value, 9) == round(alt.value, 9)
    return bool(full == alt)


def same_without_faint(t: Template, env: dict[str, Any], ctx: Context) -> str | None:
    """None when every step of the instance gives the same value on the scene without the faint objects (a set:
    the same objects apart from the faint ones; the answer: the same answer), else the reason to withhold it."""
    second = ctx.second
    faint = faint_ids(ctx.idx) | (faint_ids(second) if second is not None else frozenset())
    if not faint:
        return None
    seen = Context(seen_view(ctx.idx), ctx.rng, None if second is None else seen_view(second), prune=False)
    local = {k: v for k, v in env.items() if k in t.slots}
    prev = None
    last = t.steps[-1]
    for st, fn in zip(t.steps, t.program.fns):
        try:
            val = st.impl.replay(st, fn, local, prev, seen, env)
        except Reject:
            return NO_ANSWER
        full = env[st.name]
        if not _agree(full, val, faint) or (st is last and isinstance(full, frozenset) and not faint.isdisjoint(full)):
            return CHANGES
        local[st.name] = val
        prev = val
    return None


def withhold(t: Template, env: dict[str, Any], ctx: Context, qa: QAPair) -> str | None:
    """The reason this finished pair must not be emitted (counted in sample.meta["truth"]), or None."""
    if not metric_ok(t, env, ctx, qa):
        return METRIC
    why = photo_withhold(qa, ctx.idx.frame)  # photos: position, same-category size, incomplete categories
    if why is not None:
        return why
    return same_without_faint(t, env, ctx)
