"""superlative: the one object that wins the relation against every other (0 steps, 2 with an anchor)."""

from __future__ import annotations

from collections.abc import Collection
from typing import TYPE_CHECKING, Any

from refspatial_gen.qa.index import Reject
from refspatial_gen.qa.ops.base import OBJECT, Arg, Op
from refspatial_gen.qa.ops.common import anchored, resolve, set_in, winner
from refspatial_gen.qa.program import Ref, Step

if TYPE_CHECKING:
    from refspatial_gen.qa.values import Context
    from refspatial_gen.qa.verify_world import Run


def needs_anchor(args: dict[str, Ref]) -> tuple[tuple[str, ...], str] | None:
    """A literal anchored relation (close/far) needs an anchor: argument (shared with compare and choose)."""
    rel = args.get("relation")
    if rel is not None and rel.kind == "literal" and anchored(rel.value) and "anchor" not in args:
        return ("relation",), f"relation {rel.value!r} compares distances to an anchor: add anchor:"
    return None


class Superlative(Op):
    name = "superlative"
    args = {"in": Arg("set"), "relation": Arg("relation", True), "anchor": Arg("object")}
    out = OBJECT
    relation_uses = ("ordered", "anchored")
    doc = "the one object that wins the relation against all others (0 steps, 2 with anchor)"
    chain = needs_two = droppable = True

    def weight(self, present: Collection[str]) -> int:
        return 2 if "anchor" in present else 0

    def check(self, args: dict[str, Ref], prior: list[Step]) -> tuple[tuple[str, ...], str] | None:
        return needs_anchor(args)

    def run(self, st: Step, env: dict[str, Any], prev: Any, ctx: Context) -> Any:
        idx = ctx.idx
        a = st.args
        s = set_in(st, env, prev, idx)
        rel = resolve(a["relation"], env, prev, idx)
        anchor = resolve(a["anchor"], env, prev, idx) if "anchor" in a else None
        if anchored(rel) and anchor is None:
            raise Reject("no_anchor")
        return winner([x for x in s if x != anchor], rel, anchor, idx)

    def verify(self, run: Run, a: dict[str, Any], prev: Any, st: dict[str, Any]) -> Any:
        anchor = a.get("anchor")
        return run.most(sorted(x for x in run.input_set(a) if x != anchor), a["relation"], anchor)


OP = Superlative()
