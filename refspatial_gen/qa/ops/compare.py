"""compare: does relation(a, b[, anchor]) hold (yes/no; 2 steps, 3 with an anchor)."""

from __future__ import annotations

from collections.abc import Collection
from typing import TYPE_CHECKING, Any

from refspatial_gen.graph.relations import REGISTRY, ids_by_use
from refspatial_gen.qa.index import Reject
from refspatial_gen.qa.ops.base import BOOL, Arg, Op
from refspatial_gen.qa.ops.common import (
    EMPTY,
    MARGIN,
    NO_ANCHOR,
    NO_FACT_R,
    NOT_UNIQUE,
    SAME_OBJECT,
    anchored,
    name_of,
    resolve,
    single,
    value_of,
)
from refspatial_gen.qa.ops.superlative import needs_anchor
from refspatial_gen.qa.program import Ref, Step, StepFn

if TYPE_CHECKING:
    from refspatial_gen.qa.keysteps import KeyWriter
    from refspatial_gen.qa.values import Context
    from refspatial_gen.qa.verify_world import Run


class Compare(Op):
    name = "compare"
    args = {
        "relation": Arg("relation", True),
        "a": Arg("object", True),
        "b": Arg("object", True),
        "anchor": Arg("object"),
    }
    out = BOOL
    relation_uses = ("ordered", "pairwise", "anchored")
    doc = "does relation(a, b[, anchor]) hold (2 steps, 3 with anchor)"
    reads_single = droppable = True
    drop_to = "none"
    targets_for, target_args = BOOL, ("a", "b")

    def weight(self, present: Collection[str]) -> int:
        return 3 if "anchor" in present else 2

    def check(self, args: dict[str, Ref], prior: list[Step]) -> tuple[tuple[str, ...], str] | None:
        return needs_anchor(args)

    def run(self, st: Step, env: dict[str, Any], prev: Any, ctx: Context) -> Any:
        idx = ctx.idx
        a = st.args
        rel = resolve(a["relation"], env, prev, idx)
        x, y = single(resolve(a["a"], env, prev, idx)), single(resolve(a["b"], env, prev, idx))
        anchor = resolve(a["anchor"], env, prev, idx) if "anchor" in a else None
        if x == y or (anchor is not None and anchor in (x, y)):
            raise Reject("same_object")
        if anchored(rel):
            if anchor is None:
                raise Reject("no_anchor")
            return idx.holds(rel, (x, y, anchor))
        return idx.holds(rel, (x, y))

    def compile(self, st: Step) -> StepFn | None:
        a = st.args
        rel, an, bn = value_of(a["relation"]), name_of(a["a"]), name_of(a["b"])
        cn = name_of(a.get("anchor"))
        if rel is None or an is None or bn is None or (a.get("anchor") is not None and cn is None):
            return None
        rel_name, rel_lit = rel
        with_anchor = frozenset(ids_by_use("anchored"))  # the relations known when the template compiles

        def fn(env: dict[str, Any], prev: Any, ctx: Any) -> Any:
            r = rel_lit if rel_name is None else env[rel_name]
            x, y = env[an], env[bn]
            if x.__class__ is frozenset:
                if len(x) != 1:
                    return NOT_UNIQUE if x else EMPTY
                x = next(iter(x))
            if y.__class__ is frozenset:
                if len(y) != 1:
                    return NOT_UNIQUE if y else EMPTY
                y = next(iter(y))
            anchor = env[cn] if cn is not None else None
            if x == y or (anchor is not None and (anchor == x or anchor == y)):
                return SAME_OBJECT
            if r in with_anchor:
                if anchor is None:
                    return NO_ANCHOR
                h = ctx.idx.decision(r, (x, y, anchor))
            else:
                h = ctx.idx.decision(r, (x, y))
            if h is True or h is False:
                return h
            return MARGIN if h is None else NO_FACT_R

        return fn

    def key_extra(self, st: Step) -> Any:
        return st.args["a"].value  # the object whose orientation an orientation relation reads

    def key_steps(self, st: Step, extra: Any, env: dict[str, Any], rel: str | None, keys: KeyWriter) -> None:
        if rel is not None and REGISTRY[rel].key_step == "Orientation":
            keys.orient(keys.one(env[extra]))

    def verify(self, run: Run, a: dict[str, Any], prev: Any, st: dict[str, Any]) -> Any:
        rel, x, y = a["relation"], run.one(a["a"]), run.one(a["b"])
        if run.anchored(rel):
            return run.w.holds(rel, x, y, a["anchor"])
        return run.w.holds(rel, x, y)


OP = Compare()
