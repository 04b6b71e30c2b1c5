"""Template steps compiled to closures for the search's inner loop.

Why: the search executes tens of steps per emitted question, and most fail at once (a relation inside its
margin, an empty or unchanged set). Interpreting a step (dispatch on the op name, resolving each argument,
raising and catching an exception per failure) costs several times the lookup itself. A compiled step binds
its argument names once and returns a rejection as a value. The hot ops (relate, between, filter, locate,
compare) get their own closure; every other op runs through `run_step` unchanged. `run_step` stays the
reference: tests check that compiled and interpreted steps agree on every binding of every template and
on the bindings the search reaches.
"""

from __future__ import annotations

from typing import Any, Callable

from refspatial_gen.qa.executor import PointValue
from refspatial_gen.qa.index import Reject
from refspatial_gen.qa.ops import ANCHORED
from refspatial_gen.qa.templates import Ref, Step, Template

StepFn = Callable[[dict, Any, Any], Any]  # (env, prev, ctx) -> value, or a Reject instance (returned, not raised)

EMPTY, MARGIN, NO_FACT = Reject("empty"), Reject("margin"), Reject("no_fact")
NO_NARROWING, BOUND = Reject("no_narrowing"), Reject("bound")


def _name(ref: Ref | None) -> str | None:
    """The env key a slot/step reference reads, or None for other kinds."""
    return ref.value if ref is not None and ref.kind in ("slot", "step") else None


def _generic(st: Step) -> StepFn:
    from refspatial_gen.qa.executor import _OPS

    impl = _OPS.get(st.op)
    if impl is None:
        raise ValueError(f"unknown op {st.op}")

    def fn(env: dict, prev: Any, ctx: Any) -> Any:
        try:
            return impl(st, env, prev, ctx)
        except Reject as r:
            # returned, not raised: drop the traceback, whose frames would otherwise hold the exception (and
            # through the frames' locals the whole scene index) in a reference cycle only the collector frees
            r.__traceback__ = None
            return r
    return fn


def _relate(st: Step) -> StepFn | None:
    a = st.args
    rn, an = _name(a["relation"]), _name(a["anchor"])
    if rn is None or an is None or a.get("in") is not None:
        return None
    min_out, exact = st.min_out, st.exact_one

    def fn(env: dict, prev: Any, ctx: Any) -> Any:
        idx = ctx.idx
        s = prev if prev.__class__ is frozenset else idx.all
        t, u, m = idx.rel_entry(env[rn], env[an])
        if u and not u.isdisjoint(s):
            return MARGIN
        if m and not m.isdisjoint(s):
            return NO_FACT
        out = s & t
        n = len(out)
        if not n:
            return EMPTY
        if ctx.prune:
            if n == len(s):
                return NO_NARROWING
            if n < min_out or (exact and n != 1):
                return BOUND
        return out
    return fn


def _between(st: Step) -> StepFn | None:
    a = st.args
    anchors = a["anchors"]
    if a.get("in") is not None or anchors.kind != "list" or len(anchors.value) != 2:
        return None
    bn, cn = _name(anchors.value[0]), _name(anchors.value[1])
    if bn is None or cn is None:
        return None
    min_out, exact = st.min_out, st.exact_one
    slow = _generic(st)

    def fn(env: dict, prev: Any, ctx: Any) -> Any:
        idx = ctx.idx
        s = prev if prev.__class__ is frozenset else idx.all
        t, u, m = idx.between_entry(env[bn], env[cn])
        if m:
            if not m.isdisjoint(s) or (u and not u.isdisjoint(s)):
                return slow(env, prev, ctx)  # the reference path names the reason (first bad member)
        elif u and not u.isdisjoint(s):
            return MARGIN  # every bad member is undecided (none lacks a fact): the reference says "margin"
        out = s & t
        n = len(out)
        if not n:
            return EMPTY
        if ctx.prune:
            if n == len(s):
                return NO_NARROWING
            if n < min_out or (exact and n != 1):
                return BOUND
        return out
    return fn


NOT_UNIQUE, SAME_OBJECT, NO_ANCHOR, NO_POINT = (Reject("not_unique"), Reject("same_object"), Reject("no_anchor"),
                                                Reject("no_point"))
_EMPTY_SET: frozenset = frozenset()


def _value_of(ref: Ref | None) -> tuple[str | None, Any] | None:
    """(env name, None) for a slot/step reference, (None, value) for a literal, None for anything else."""
    if ref is None:
        return None
    if ref.kind in ("slot", "step"):
        return ref.value, None
    if ref.kind == "literal":
        return None, ref.value
    return None


def _filter(st: Step) -> StepFn | None:
    a = st.args
    if a.get("in") is not None:
        return None
    parts = {k: _value_of(a.get(k)) for k in ("category", "color", "on") if k in a}
    if any(v is None for v in parts.values()):
        return None
    cat, col, on = parts.get("category"), parts.get("color"), parts.get("on")
    min_out, exact = st.min_out, st.exact_one

    def fn(env: dict, prev: Any, ctx: Any) -> Any:
        idx = ctx.idx
        s = prev if prev.__class__ is frozenset else idx.all
        if cat is not None:
            s = s & idx.by_category.get(cat[1] if cat[0] is None else env[cat[0]], _EMPTY_SET)
        if col is not None:
            s = s & idx.by_color.get(col[1] if col[0] is None else env[col[0]], _EMPTY_SET)
        if on is not None:
            sid, on_map = (on[1] if on[0] is None else env[on[0]]), idx.on
            s = frozenset([i for i in s if sid in on_map.get(i, ())])
        if not s:
            return EMPTY
        if ctx.prune and (len(s) < min_out or (exact and len(s) != 1)):
            return BOUND
        return s
    return fn


def _locate(st: Step) -> StepFn | None:
    ref = st.args.get("of")
    of = _name(ref)
    if ref is not None and of is None:
        return None

    def fn(env: dict, prev: Any, ctx: Any) -> Any:
        v = prev if of is None else env[of]
        if v.__class__ is frozenset:
            if len(v) != 1:
                return NOT_UNIQUE if v else EMPTY
            v = next(iter(v))
        p = ctx.idx.nodes[v].point
        if p is None:
            return NO_POINT
        return PointValue((float(p[0]), float(p[1])), v)
    return fn


def _compare(st: Step) -> StepFn | None:
    a = st.args
    rel, an, bn = _value_of(a["relation"]), _name(a["a"]), _name(a["b"])
    cn = _name(a.get("anchor"))
    if rel is None or an is None or bn is None or (a.get("anchor") is not None and cn is None):
        return None
    rel_name, rel_lit = rel

    def fn(env: dict, prev: Any, ctx: Any) -> Any:
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
        if r in ANCHORED:
            if anchor is None:
                return NO_ANCHOR
            h = ctx.idx.decision(r, (x, y, anchor))
        else:
            h = ctx.idx.decision(r, (x, y))
        if h is True or h is False:
            return h
        return MARGIN if h is None else NO_FACT
    return fn


COMPILERS: dict[str, Callable[[Step], StepFn | None]] = {
    "relate": _relate, "between": _between, "filter": _filter, "locate": _locate, "compare": _compare}


def compile_step(st: Step) -> StepFn:
    """The fastest equivalent of run_step(st, ...) for this step."""
    c = COMPILERS.get(st.op)
    fn = c(st) if c is not None else None
    return fn if fn is not None else _generic(st)


def compiled(t: Template) -> list[StepFn]:
    """The template's steps compiled once (kept on the template object)."""
    fns = t.__dict__.get("_compiled")
    if fns is None:
        fns = t.__dict__["_compiled"] = [compile_step(st) for st in t.steps]
    return fns
