"""Referring expressions nest at most one level: a phrase used inside another's relative clause names its
object directly ("the shortest basket"), never through a third ("the basket closest to the orange").

Why: audit round 2 (sim:000020/v0:07) read "the basket that is bigger than the shortest basket that is
closest to the basket closest to the orange" as one stacked reference; English attaches every following
clause to the nearest noun, so a person cannot tell which object each clause describes. The anchors of the
steps that narrow the described object's set (relate, superlative, between, ...: `Op.chain`) and of
`choose` ("the marked object farthest from {anchor}") are rendered inside its relative clauses; when one
of their phrases is itself anchored the pair is withheld (`phrase_nested`, counted in sample.meta["truth"]
per withheld attempt).
"""

from __future__ import annotations

from typing import Any

from refspatial_gen.graph.phrases import anchored
from refspatial_gen.qa.program import Ref, Template
from refspatial_gen.qa.values import Context

NESTED = "phrase_nested"
DESCRIBING = ("choose",)  # not chain ops, but worded "the object {rel.sup} {anchor}" too


def _slots(ref: Ref) -> list[str]:
    if ref.kind == "slot":
        return [ref.value]
    if ref.kind == "list":
        return [x.value for x in ref.value if x.kind == "slot"]
    return []


def nested_phrase(t: Template, env: dict[str, Any], ctx: Context) -> str | None:
    """NESTED when an object named inside a relative clause of the described object has an anchored phrase."""
    phrase = ctx.idx.phrase
    for st in t.steps:
        if not (st.impl.chain or st.op in DESCRIBING):
            continue
        for ref in st.args.values():
            for name in _slots(ref):
                if t.slots[name].type not in ("object", "anchor"):
                    continue
                v = env.get(name)
                if v is not None and anchored(phrase.get(v, "")):
                    return NESTED
    return None
