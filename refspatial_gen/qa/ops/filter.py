"""filter: keep the objects of a category / colour / standing on a surface (intrinsic: 0 steps)."""

from __future__ import annotations

from typing import TYPE_CHECKING, Any

from refspatial_gen.qa.index import Reject
from refspatial_gen.qa.ops.base import SET, Arg, Op
from refspatial_gen.qa.ops.common import BOUND, EMPTY, EMPTY_SET, resolve, set_in, value_of
from refspatial_gen.qa.program import Step, StepFn

if TYPE_CHECKING:
    from refspatial_gen.qa.values import Context
    from refspatial_gen.qa.verify_world import Run


class Filter(Op):
    name = "filter"
    args = {"in": Arg("set"), "category": Arg("category"), "color": Arg("color"), "on": Arg("surface")}
    out = SET
    doc = "keep objects of a category / colour / standing on a surface (intrinsic: 0 steps)"
    chain = True

    def run(self, st: Step, env: dict[str, Any], prev: Any, ctx: Context) -> Any:
        idx = ctx.idx
        a = st.args
        s = set_in(st, env, prev, idx)
        if "category" in a:
            s = s & idx.by_category.get(resolve(a["category"], env, prev, idx), frozenset())
        if "color" in a:
            s = s & idx.by_color.get(resolve(a["color"], env, prev, idx), frozenset())
        if "on" in a:
            sid = resolve(a["on"], env, prev, idx)
            s = frozenset(i for i in s if sid in idx.on.get(i, ()))
        if not s:
            raise Reject("empty")
        if ctx.prune and (len(s) < st.min_out or (st.exact_one and len(s) != 1)):
            raise Reject("bound")
        return s

    def compile(self, st: Step) -> StepFn | None:
        a = st.args
        if a.get("in") is not None:
            return None
        parts = {k: value_of(a.get(k)) for k in ("category", "color", "on") if k in a}
        if any(v is None for v in parts.values()):
            return None
        cat, col, on = parts.get("category"), parts.get("color"), parts.get("on")
        min_out, exact = st.min_out, st.exact_one

        def fn(env: dict[str, Any], prev: Any, ctx: Any) -> Any:
            idx = ctx.idx
            s = prev if prev.__class__ is frozenset else idx.all
            if cat is not None:
                s = s & idx.by_category.get(cat[1] if cat[0] is None else env[cat[0]], EMPTY_SET)
            if col is not None:
                s = s & idx.by_color.get(col[1] if col[0] is None else env[col[0]], EMPTY_SET)
            if on is not None:
                sid, on_map = (on[1] if on[0] is None else env[on[0]]), idx.on
                s = frozenset([i for i in s if sid in on_map.get(i, ())])
            if not s:
                return EMPTY
            if ctx.prune and (len(s) < min_out or (exact and len(s) != 1)):
                return BOUND
            return s

        return fn

    def verify(self, run: Run, a: dict[str, Any], prev: Any, st: dict[str, Any]) -> Any:
        w = run.w
        s = run.input_set(a)
        s = s if s is not None else frozenset(w.nodes)
        if "category" in a:
            s = frozenset(i for i in s if w.nodes[i].category == a["category"])
        if "color" in a:
            s = frozenset(i for i in s if w.nodes[i].attributes.get("color") == a["color"])
        if "on" in a:
            s = frozenset(i for i in s if w.on_surface(i, a["on"]))
        return s


OP = Filter()
