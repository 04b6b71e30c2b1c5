"""Size questions only about objects a viewer sees whole: a finished pair recording a size relation (tall,
short, big, small, wide, thin: comparisons, superlatives, ordinals, height and width values) is withheld when
an object its program binds or computes (sets included: "the tallest glass" needs every glass) is cut by the
image border (node attribute `sized: false`, graph/visibility.py), or when its text uses a size superlative
("the smallest bicycle", also inside a referring phrase) for a category with such an object, or with one whose
size the graph does not trust (`metric: false`).

Why: a wine glass cut by the bottom edge looks tallest because it is nearest; a person cannot judge how tall
or wide the part outside the picture is (audit round 2). Distances and depths stay: the object's place is
seen. Counted in sample.meta["truth"] as `size_withheld_cut_by_border`; verify re-checks the named objects
from their stored masks and boxes (qa/verify_truth.py).

Likewise a camera turn to face an object (rotation_horizontal / rotation_vertical) is asked only about a target
seen whole: the centre of a train that runs past both edges of the photo is nowhere a person can point to, and
"rotate left around 3 degrees" to face it cannot be judged (audit round 5). Counted as
`rotation_withheld_cut_by_border`; verify re-checks the targets the same way.
"""

from __future__ import annotations

import re
from typing import Any

from refspatial_gen.core.model import QAPair
from refspatial_gen.graph.relations import REGISTRY
from refspatial_gen.qa.faint import binds_flagged
from refspatial_gen.qa.program import Template
from refspatial_gen.qa.values import Context

SIZE_RELATIONS = frozenset(n for n in REGISTRY.names() if REGISTRY[n].group == "sizes")
SIZE_CUT = "size_withheld_cut_by_border"
ROTATION_RELATIONS = frozenset({"rotation_horizontal", "rotation_vertical"})
ROTATION_CUT = "rotation_withheld_cut_by_border"
SUPERLATIVE = r"\b(?:tallest|shortest|biggest|smallest|largest|widest|thinnest)\s+(?:\w+\s+)?"


def superlative_of(question: str, category: str) -> bool:
    """Does the text use a size superlative for this category ("the smallest [red] bicycle")?"""
    cat = re.escape(category.replace("_", " ").strip().lower())
    return re.search(SUPERLATIVE + cat + r"\b", question.lower()) is not None


def target_cut(ctx: Context, qa: QAPair) -> bool:
    """Is a target of the pair (the object a camera turn faces) cut by the image border in either view?"""
    for ix in (ctx.idx, ctx.second):
        if ix is None:
            continue
        for i in qa.targets:
            n = ix.nodes.get(i)
            if n is not None and n.attributes.get("sized") is False:
                return True
    return False


def withhold_cut(t: Template, env: dict[str, Any], ctx: Context, qa: QAPair) -> str | None:
    """SIZE_CUT when the pair asks a size question involving an object cut by the border, ROTATION_CUT when it
    asks a camera turn to face a target cut by the border, else None."""
    if not ROTATION_RELATIONS.isdisjoint(qa.relations) and target_cut(ctx, qa):
        return ROTATION_CUT
    for ix in (ctx.idx, ctx.second):
        if ix is None:
            continue
        for node in ix.nodes.values():
            bad = node.attributes.get("sized") is False or node.attributes.get("metric") is False
            if bad and superlative_of(qa.question, node.category):
                return SIZE_CUT
    if SIZE_RELATIONS.isdisjoint(qa.relations):
        return None
    return SIZE_CUT if binds_flagged(t, env, ctx, "sized") else None
