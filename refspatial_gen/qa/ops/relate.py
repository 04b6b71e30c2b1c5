"""relate: keep the objects x with relation(x, anchor) (anchor + directional phrase: 2 steps)."""

from __future__ import annotations

from collections.abc import Collection
from typing import TYPE_CHECKING, Any

from refspatial_gen.graph.relations import REGISTRY
from refspatial_gen.qa.ops.base import SET, Arg, Op
from refspatial_gen.qa.ops.common import (
    MARGIN,
    NO_FACT_R,
    bounded,
    name_of,
    narrowed,
    resolve,
    set_in,
)
from refspatial_gen.qa.program import Step, StepFn

if TYPE_CHECKING:
    from refspatial_gen.qa.keysteps import KeyWriter
    from refspatial_gen.qa.values import Context
    from refspatial_gen.qa.verify_world import Run


class Relate(Op):
    name = "relate"
    args = {"in": Arg("set"), "relation": Arg("relation", True), "anchor": Arg("object", True)}
    out = SET
    relation_uses = ("ordered", "pairwise")
    doc = "keep objects x with relation(x, anchor) (anchor + phrase: 2 steps)"
    narrowing = chain = droppable = True

    def weight(self, present: Collection[str]) -> int:
        return 2

    def run(self, st: Step, env: dict[str, Any], prev: Any, ctx: Context) -> Any:
        idx = ctx.idx
        a = st.args
        s = set_in(st, env, prev, idx)
        r, r2 = a["relation"], a["anchor"]
        rel = env[r.value] if r.kind == "slot" or r.kind == "step" else resolve(r, env, prev, idx)
        anchor = env[r2.value] if r2.kind == "slot" or r2.kind == "step" else resolve(r2, env, prev, idx)
        return bounded(st, s, idx.narrow(rel, anchor, s), ctx)

    def compile(self, st: Step) -> StepFn | None:
        a = st.args
        rn, an = name_of(a["relation"]), name_of(a["anchor"])
        if rn is None or an is None or a.get("in") is not None:
            return None
        min_out, exact = st.min_out, st.exact_one

        def fn(env: dict[str, Any], prev: Any, ctx: Any) -> Any:
            idx = ctx.idx
            s = prev if prev.__class__ is frozenset else idx.all
            t, u, m = idx.rel_entry(env[rn], env[an])
            if u and not u.isdisjoint(s):
                return MARGIN
            if m and not m.isdisjoint(s):
                return NO_FACT_R
            return narrowed(s, s & t, ctx.prune, min_out, exact)

        return fn

    def key_steps(self, st: Step, extra: Any, env: dict[str, Any], rel: str | None, keys: KeyWriter) -> None:
        if rel is not None and REGISTRY[rel].key_step == "Orientation":
            keys.final_orient = True  # the answer object's own orientation decides the relation

    def verify(self, run: Run, a: dict[str, Any], prev: Any, st: dict[str, Any]) -> Any:
        s = run.input_set(a)
        return frozenset(x for x in s if x != a["anchor"] and run.w.holds(a["relation"], x, a["anchor"]))


OP = Relate()
