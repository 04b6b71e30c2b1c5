"""Helpers the op modules share: argument resolution, early-pruning bounds, the superlative winner rule,
and the rejections compiled steps return (shared constants: returning one costs nothing)."""

from __future__ import annotations

from typing import Any

from refspatial_gen.graph.constants import Thresholds
from refspatial_gen.graph.relations import REGISTRY
from refspatial_gen.graph.relations.distances import centre_agrees, close_margin
from refspatial_gen.qa.index import NO_FACT, Reject, SceneIndex
from refspatial_gen.qa.program import Ref, Step, StepFn
from refspatial_gen.qa.values import Context

EMPTY, MARGIN, NO_FACT_R = Reject("empty"), Reject("margin"), Reject("no_fact")
NO_NARROWING, BOUND = Reject("no_narrowing"), Reject("bound")
NOT_UNIQUE, SAME_OBJECT, NO_ANCHOR, NO_POINT = (
    Reject("not_unique"),
    Reject("same_object"),
    Reject("no_anchor"),
    Reject("no_point"),
)
EMPTY_SET: frozenset[int] = frozenset()


def narrowed(s: frozenset[int], out: frozenset[int], prune: bool, min_out: int, exact: bool) -> Any:
    """A filter's result `out` of the set `s`, or why it is rejected: empty; when pruning, no narrowing or
    fewer than `min_out` left (or not exactly one when the step must pick one)."""
    n = len(out)
    if not n:
        return EMPTY
    if prune:
        if n == len(s):
            return NO_NARROWING
        if n < min_out or (exact and n != 1):
            return BOUND
    return out


_RELATIONS = REGISTRY.loaded  # id -> Relation, a plain dict read on the hot path


def anchored(relation: str) -> bool:
    """Does the relation compare distances to an anchor (close/far: three arguments)?"""
    rel = _RELATIONS.get(relation) or REGISTRY[relation]
    return rel.qa == "anchored"


def resolve(ref: Ref | None, env: dict[str, Any], prev: Any, idx: SceneIndex) -> Any:
    if ref is None:
        return prev
    k = ref.kind
    if k == "slot" or k == "step":
        return env[ref.value]
    if k == "literal":
        return ref.value
    if k == "all":
        return idx.all
    if k == "list":
        return tuple(resolve(r, env, prev, idx) for r in ref.value)
    raise ValueError(f"unknown ref kind {k}")


def set_in(st: Step, env: dict[str, Any], prev: Any, idx: SceneIndex) -> frozenset[int]:
    """The step's input set: its `in` argument, else the previous step's set, else every object."""
    r = st.args.get("in")
    if r is None:
        return prev if isinstance(prev, frozenset) else idx.all
    return resolve(r, env, prev, idx)


def single(v: Any) -> int:
    """One object from a step's value (a set must hold exactly one)."""
    if isinstance(v, frozenset):
        if len(v) != 1:
            raise Reject("not_unique" if v else "empty")
        return next(iter(v))
    return v


def bounded(st: Step, before: frozenset[int], out: frozenset[int], ctx: Context) -> frozenset[int]:
    """Early pruning: a narrowing step that removes nothing is degenerate; later steps need room."""
    n = len(out)
    if n == 0:
        raise Reject("empty")
    if not ctx.prune:
        return out
    if n == len(before):
        raise Reject("no_narrowing")
    if n < st.min_out or (st.exact_one and n != 1):
        raise Reject("bound")
    return out


def name_of(ref: Ref | None) -> str | None:
    """The env key a slot/step reference reads, or None for other kinds."""
    return ref.value if ref is not None and ref.kind in ("slot", "step") else None


def value_of(ref: Ref | None) -> tuple[str | None, Any] | None:
    """(env name, None) for a slot/step reference, (None, value) for a literal, None for anything else."""
    if ref is None:
        return None
    if ref.kind in ("slot", "step"):
        return ref.value, None
    if ref.kind == "literal":
        return None, ref.value
    return None


def generic(st: Step) -> StepFn:
    """The op's interpreter as a step function (a Reject is returned, not raised)."""
    impl = st.impl.run

    def fn(env: dict[str, Any], prev: Any, ctx: Any) -> Any:
        try:
            return impl(st, env, prev, ctx)
        except Reject as r:
            # returned, not raised: drop the traceback, whose frames would otherwise hold the exception (and
            # through the frames' locals the whole scene index) in a reference cycle only the collector frees
            r.__traceback__ = None
            return r

    return fn


def winner(cands: Any, rel: str, anchor: int | None, idx: SceneIndex) -> int:
    """The one candidate for which rel(x, y[, anchor]) decidedly holds against every other. Undecided
    comparisons between two losers do not matter; if no candidate wins and one was undecided -> margin."""
    cands = sorted(cands)
    if not cands:
        raise Reject("empty")
    is_anchored = anchored(rel)
    if is_anchored and anchor is not None:
        d = idx.distances_to(anchor, cands)
        if d is not None:
            c, tied = idx.centres_to(anchor, cands)
            if tied and len(cands) > 1:  # one candidate is compared with nothing (as the pairwise path)
                raise Reject("distance_supported")
            return nearest_winner(cands, d, REGISTRY[rel].mirror_of is not None, idx.tables.th, c)  # type: ignore[arg-type]
    # a quick elimination pass finds the only possible winner, then it is checked against everyone
    decision = idx.decision

    def args(x: int, y: int) -> tuple[int, ...]:
        return (x, y, anchor) if is_anchored else (x, y)  # type: ignore[return-value]

    best = cands[0]
    for y in cands[1:]:
        h = decision(rel, args(best, y))
        if h is NO_FACT:
            raise Reject("no_fact")
        if h is False or h is None and decision(rel, args(y, best)) is True:
            best = y
    undecided = False
    for y in cands:
        if y == best:
            continue
        h = decision(rel, args(best, y))
        if h is NO_FACT:
            raise Reject("no_fact")
        if h is None:
            undecided = True
        elif not h:
            raise Reject("no_winner")
    if undecided:
        raise Reject("margin")
    return best


def nearest_winner(
    cands: list[int], d: list[float], farthest: bool, th: Thresholds, c: list[float] | None = None
) -> int:
    """winner() for close/far from the distances of the candidates to the anchor: close(x, y, c) holds when
    d(y, c) - d(x, c) exceeds close_margin (distance_margin and distance_margin_rel of the larger; far: the
    other way round), so the winner is the nearest (farthest) candidate, and it wins only if it beats the
    runner-up by that margin (the runner-up is the hardest to beat). Same answer as the pairwise rule."""
    if len(cands) == 1:
        return cands[0]
    k = max(range(len(d)), key=d.__getitem__) if farthest else min(range(len(d)), key=d.__getitem__)
    best = d[k]
    runner = max(v for i, v in enumerate(d) if i != k) if farthest else min(v for i, v in enumerate(d) if i != k)
    gap = (best - runner) if farthest else (runner - best)
    if gap <= close_margin(best, runner, th):
        raise Reject("margin")
    if c is not None:  # the centres must put the winner ahead of every other by their own margin too
        if not all(centre_agrees(c[k], v, farthest, th) for i, v in enumerate(c) if i != k):
            raise Reject("distance_centre_disagrees")
    return cands[k]
