"""ordinal: the rank-th object along an ordering relation (image position: 0 steps)."""

from __future__ import annotations

from typing import TYPE_CHECKING, Any

from refspatial_gen.qa.index import Reject
from refspatial_gen.qa.ops.base import OBJECT, Arg, Op
from refspatial_gen.qa.ops.common import resolve, set_in
from refspatial_gen.qa.program import Step

if TYPE_CHECKING:
    from refspatial_gen.qa.values import Context
    from refspatial_gen.qa.verify_world import Run


class Ordinal(Op):
    name = "ordinal"
    args = {"in": Arg("set"), "relation": Arg("relation", True), "rank": Arg("number", True)}
    out = OBJECT
    relation_uses = ("ordered",)
    doc = "the rank-th object along the relation's order (image position: 0 steps)"
    chain = needs_two = droppable = True

    def run(self, st: Step, env: dict[str, Any], prev: Any, ctx: Context) -> Any:
        idx = ctx.idx
        a = st.args
        s = sorted(set_in(st, env, prev, idx))
        rel = resolve(a["relation"], env, prev, idx)
        rank = resolve(a["rank"], env, prev, idx)
        n = len(s)
        if rank > n or n < 2:
            raise Reject("rank")
        wins = {x: 0 for x in s}
        for i, x in enumerate(s):
            for y in s[i + 1 :]:
                if idx.holds(rel, (x, y)):
                    wins[x] += 1
                else:
                    wins[y] += 1
        for x in s:
            if wins[x] == n - rank:
                return x
        raise Reject("rank")

    def verify(self, run: Run, a: dict[str, Any], prev: Any, st: dict[str, Any]) -> Any:
        cands = sorted(run.input_set(a))
        n = len(cands)
        wins = {x: sum(1 for y in cands if y != x and run.w.holds(a["relation"], x, y)) for x in cands}
        hit = [x for x in cands if wins[x] == n - int(a["rank"])]
        if len(hit) != 1:
            raise run.fail(f"ordinal: no unique rank {a['rank']} among {cands}")
        return hit[0]


OP = Ordinal()
