"""between: keep the objects between two anchors (2 anchors + phrase: 3 steps)."""

from __future__ import annotations

from collections.abc import Collection
from typing import TYPE_CHECKING, Any

from refspatial_gen.qa.ops.base import SET, Arg, Op, Recorded
from refspatial_gen.qa.ops.common import MARGIN, bounded, generic, name_of, narrowed, resolve, set_in
from refspatial_gen.qa.program import Ref, Step, StepFn

if TYPE_CHECKING:
    from refspatial_gen.qa.values import Context
    from refspatial_gen.qa.verify_world import Run


class Between(Op):
    name = "between"
    args = {"in": Arg("set"), "anchors": Arg("objects", True)}
    out = SET
    doc = "keep objects between two anchors (2 anchors + phrase: 3 steps)"
    narrowing = chain = droppable = True

    def weight(self, present: Collection[str]) -> int:
        return 3

    def check(self, args: dict[str, Ref], prior: list[Step]) -> tuple[tuple[str, ...], str] | None:
        r = args.get("anchors")
        if r is not None and len(r.value) != 2:
            return ("anchors",), "anchors must list exactly two objects"
        return None

    def needs(self, st: Step) -> dict[str, Any]:
        return {"between": max(st.min_out, 1)}

    def recorded(self, st: Step) -> Recorded:
        return Recorded(relations=("between",))

    def run(self, st: Step, env: dict[str, Any], prev: Any, ctx: Context) -> Any:
        idx = ctx.idx
        s = set_in(st, env, prev, idx)
        b, c = resolve(st.args["anchors"], env, prev, idx)
        return bounded(st, s, idx.between(b, c, s), ctx)

    def compile(self, st: Step) -> StepFn | None:
        a = st.args
        anchors = a["anchors"]
        if a.get("in") is not None or anchors.kind != "list" or len(anchors.value) != 2:
            return None
        bn, cn = name_of(anchors.value[0]), name_of(anchors.value[1])
        if bn is None or cn is None:
            return None
        min_out, exact = st.min_out, st.exact_one
        slow = generic(st)

        def fn(env: dict[str, Any], prev: Any, ctx: Any) -> Any:
            idx = ctx.idx
            s = prev if prev.__class__ is frozenset else idx.all
            t, u, m = idx.between_entry(env[bn], env[cn])
            if m:
                if not m.isdisjoint(s) or (u and not u.isdisjoint(s)):
                    return slow(env, prev, ctx)  # the reference path names the reason (first bad member)
            elif u and not u.isdisjoint(s):
                return MARGIN  # every bad member is undecided (none lacks a fact): the reference says "margin"
            return narrowed(s, s & t, ctx.prune, min_out, exact)

        return fn

    def verify(self, run: Run, a: dict[str, Any], prev: Any, st: dict[str, Any]) -> Any:
        b, c = a["anchors"]
        s = run.input_set(a)
        return frozenset(x for x in s if x not in (b, c) and run.w.holds("between", x, b, c))


OP = Between()
