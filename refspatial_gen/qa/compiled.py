"""Template steps compiled to closures for the search's inner loop.

Why: the search executes tens of steps per emitted question, and most fail at once (a relation inside its
margin, an empty or unchanged set). Interpreting a step (dispatch on the op name, resolving each argument,
raising and catching an exception per failure) costs several times the lookup itself. A compiled step binds
its argument names once and returns a rejection as a value. The hot ops (relate, between, filter, locate)
get their own closure; every other op runs through `run_step` unchanged. `run_step` stays the reference:
a test checks that compiled and interpreted steps agree on every binding of every template.
"""

from __future__ import annotations

from typing import Any, Callable

from refspatial_gen.qa.index import Reject
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


COMPILERS: dict[str, Callable[[Step], StepFn | None]] = {"relate": _relate, "between": _between}


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
