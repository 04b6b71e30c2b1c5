"""Run a compiled template program against one frame: bind slots by search, execute typed steps, and
check that no counted step is degenerate.

Why a search with pruning: most random bindings of a template fail (the relation does not hold, the
result is empty or not unique). Binding slots in the order the program first needs them and running each
step as soon as its slots are bound cuts a failing branch at the first step that fails, so the engine
tries many bindings per millisecond. Every intermediate result is kept for the trace and the checks.
What each step does is its op's business (qa/ops/); this module only walks programs.
"""

from __future__ import annotations

from collections.abc import Callable, Iterator
from itertools import product
from typing import Any

import numpy as np

from refspatial_gen.qa.index import Reject
from refspatial_gen.qa.ops.base import FREE_KINDS, REGION_KINDS, SET
from refspatial_gen.qa.ops.common import generic
from refspatial_gen.qa.program import Step, StepFn, Template
from refspatial_gen.qa.sample_rng import SampleRng
from refspatial_gen.qa.values import Context, NumberValue, OptionValue, PointValue

__all__ = [
    "Context",
    "NumberValue",
    "OptionValue",
    "PointValue",
    "Search",
    "answer_chain",
    "answer_key",
    "compile_step",
    "degenerate_steps",
    "replay",
    "run_step",
    "slot_candidates",
]


def run_step(st: Step, env: dict[str, Any], prev: Any, ctx: Context) -> Any:
    """Execute one step (the reference interpreter); raise Reject when the step has no well-defined result."""
    return st.impl.run(st, env, prev, ctx)


def compile_step(st: Step) -> StepFn:
    """The fastest equivalent of run_step(st, ...): the op's compiled form, else its interpreter."""
    fn = st.impl.compile(st)
    return fn if fn is not None else generic(st)


def answer_chain(steps: list[Step]) -> tuple[bool, ...]:
    """Per step: is the answer object certainly a member of this step's output set? True for the set steps
    of a chain that ends in a step locating its input's object, where every later step narrows its
    predecessor's output (no `in` of its own). The search uses it to drop a branch as soon as no answer it
    can reach would pass the answer-position balance (generate.Balancer), instead of finding each such
    answer and rejecting it."""
    n = len(steps)
    flags = [False] * n
    if n < 2 or not steps[-1].impl.locates or steps[-1].args.get("of") is not None:
        return tuple(flags)
    # the answer is the one member of step n-2's output (or that step's object, for superlative/ordinal)
    for j in range(n - 2, -1, -1):
        impl = steps[j].impl
        if impl.chain and impl.out == SET:
            flags[j] = True
        elif not (j == n - 2 and impl.chain):
            break
        # step j's input set holds the answer: the previous step's output, when step j reads no `in` of its own
        if steps[j].args.get("in") is not None:
            break
    return tuple(flags)


# ---------------------------------------------------------------------------------------------- slots
def slot_candidates(t: Template, name: str, env: dict[str, Any], ctx: Context) -> list[Any]:
    """The values a slot may take in this frame (unshuffled, deterministic order)."""
    s = t.slots[name]
    idx = ctx.idx
    if s.type in ("object", "anchor"):
        used = {v for k, v in env.items() if k in t.slots and t.slots[k].type in ("object", "anchor")}
        out = [i for i in idx.referable if i not in used]
        if s.category:
            out = [i for i in out if idx.category[i] in s.category]
        if s.has_front:
            out = [i for i in out if idx.has_front.get(i)]
        return out
    if s.type == "relation":
        return list(s.choices or ())
    if s.type == "direction":
        return list(s.choices or FREE_KINDS[:4])
    if s.type == "number":
        return list(s.choices or range(s.min, s.max + 1))
    if s.type == "category":
        return [c for c in idx.categories if not s.choices or c in s.choices]
    if s.type == "color":
        return [c for c in idx.colors if not s.choices or c in s.choices]
    if s.type == "surface":
        return [
            k
            for k in sorted(idx.surfaces)
            if (not s.choices or k in s.choices) and any(k in v for v in idx.on.values())
        ]
    if s.type == "spot":
        kinds = s.kinds or REGION_KINDS
        return [sp for sp in idx.spots if sp[0] in kinds]
    if s.type == "region":
        kinds = s.kinds or REGION_KINDS
        return [r for r in idx.region_list if r.kind in kinds and r.label]
    return []


class Search:
    """Depth-first binding of a template's slots with a work budget; yields complete instances.

    Each slot's candidates are shuffled once per search (the sample's generator); object slots must bind
    distinct objects. Every executed step costs one unit of budget.
    """

    def __init__(self, t: Template, ctx: Context, budget: int, answers: frozenset[Any] | None = None) -> None:
        """`answers`: the objects the caller would accept as the answer (None = any); a branch whose output
        set on the answer chain (answer_chain) holds none of them is dropped ("balance")."""
        self.t, self.ctx, self.budget, self.answers = t, ctx, budget, answers
        self.rejects: dict[str, int] = {}
        self._cands: dict[str, list[Any]] = {}
        self._plan = t.program.search
        self._lists: list[list[Any] | None] = [None] * len(self._plan)

    def candidates(self, name: str) -> list[Any]:
        c = self._cands.get(name)
        if c is None:
            # the unshuffled list depends only on the slot's declaration and the frame: kept on the frame's
            # index under the declaration's signature, so templates declaring the same slot share it
            memo = self.ctx.idx.slot_memo
            mk = self.t.program.signatures[name]
            unshuffled = memo.get(mk)
            if unshuffled is None:
                unshuffled = memo[mk] = tuple(slot_candidates(self.t, name, {}, self.ctx))
            if len(unshuffled) < 2:
                c = list(unshuffled)
            elif isinstance(self.ctx.rng, SampleRng):
                c = self.ctx.rng.shuffled(unshuffled)
            else:  # a numpy Generator (tests and callers outside generation)
                c = [unshuffled[k] for k in self.ctx.rng.permutation(len(unshuffled))]
            self._cands[name] = c
        return c

    def instances(self) -> Iterator[dict[str, Any]]:
        """Every instance the search reaches, in search order (for tests; generation uses `first`)."""
        found: list[dict[str, Any]] = []

        def collect(env: dict[str, Any]) -> None:
            found.append(dict(env))

        self.first(collect)
        return iter(found)

    def first(self, accept: Callable[[dict[str, Any]], Any]) -> Any:
        """Walk the bindings in search order and call `accept(env)` on each complete instance; return the first
        result that is not None (None when the budget or the space runs out). `env` is the search's own
        dict: accept must copy what it keeps. Plain recursion with a callback, not nested generators: a
        generator per level and a `yield from` chain per instance cost more than the steps themselves."""
        self._accept = accept
        return self._walk(0, {}, None, frozenset())

    def _walk(self, i: int, env: dict[str, Any], prev: Any, used: frozenset[Any]) -> Any:
        st, names, objs, tries, fn, on_chain = self._plan[i]
        ctx, rejects, out = self.ctx, self.rejects, st.name
        last = i + 1 == len(self._plan)
        nxt = self._accept if last else None
        answers = self.answers if on_chain else None
        lists = self._lists[i]
        if lists is None:
            lists = self._lists[i] = [self.candidates(nm) for nm in names]
        combos = product(*lists) if names else ((),)
        n_names = len(names)
        one_obj = objs[0] if len(objs) == 1 else None
        for combo in combos:
            if self.budget <= 0:
                break
            if objs:
                if one_obj is not None:
                    if combo[one_obj] in used:
                        continue
                else:
                    vals = [combo[k] for k in objs]
                    if len(set(vals)) != len(vals) or (used and not used.isdisjoint(vals)):
                        continue
            if n_names == 1:
                env[names[0]] = combo[0]
            elif n_names == 2:
                env[names[0]], env[names[1]] = combo
            else:
                for nm, v in zip(names, combo):
                    env[nm] = v
            self.budget -= 1
            if tries == 1:  # the common case, without the retry loop
                val = fn(env, prev, ctx)
                if val.__class__ is Reject:
                    rejects[val.reason] = rejects.get(val.reason, 0) + 1
                    continue
                if answers is not None and answers.isdisjoint(val):
                    rejects["balance"] = rejects.get("balance", 0) + 1
                    continue
                env[out] = val
                if nxt is not None:
                    r = nxt(env)
                else:
                    r = self._walk(i + 1, env, val, used.union([combo[k] for k in objs]) if objs else used)
                if r is not None:
                    return r
                continue
            for _ in range(tries):
                val = fn(env, prev, ctx)
                if val.__class__ is Reject:
                    rejects[val.reason] = rejects.get(val.reason, 0) + 1
                    continue
                if answers is not None and answers.isdisjoint(val):
                    rejects["balance"] = rejects.get("balance", 0) + 1
                    continue
                env[out] = val
                if nxt is not None:
                    r = nxt(env)
                else:
                    r = self._walk(i + 1, env, val, used.union([combo[k] for k in objs]) if objs else used)
                if r is not None:
                    return r
                if self.budget <= 0:
                    break
        env.pop(out, None)
        for nm in names:
            env.pop(nm, None)
        return None


def replay(t: Template, env: dict[str, Any], ctx: Context, drop: int | None = None, reuse_prefix: bool = True) -> Any:
    """Re-run the program with the slots of `env`, optionally with step `drop` removed; returns the answer.

    A removed step gives its op's `dropped` value (a set-narrowing step passes its input through; a
    superlative/ordinal leaves its input set, an answer only if it holds one object; a yes/no step gives
    nothing, so an `all` decides without it). Raises Reject when there is no answer.
    With `reuse_prefix`, the steps before `drop` are not re-run: their results are the instance's own (a step
    depends only on the slots and earlier steps, and pruning only adds rejections, never changes a value).
    """
    if ctx.prune:
        ctx = Context(ctx.idx, ctx.rng, ctx.second, prune=False)
    prev = None
    steps, fns = t.steps, t.program.fns
    if reuse_prefix and drop:
        # every step reads only slots and earlier steps, and each step from `drop` on is rewritten before it is
        # read: the instance's own dict is the right starting point
        local = dict(env)
        prev = env[steps[drop - 1].name]
        steps, fns = steps[drop:], fns[drop:]
    else:
        local = {k: v for k, v in env.items() if k in t.slots}
    last = t.steps[-1]
    for st, fn in zip(steps, fns):
        impl = st.impl
        if st.index == drop:
            if not impl.droppable:
                raise Reject("not_droppable")
            val = impl.dropped(st, local, prev, ctx.idx)
        else:
            val = impl.replay(st, fn, local, prev, ctx, env)
        if val is None and st is last:
            raise Reject("empty")
        local[st.name] = val
        prev = val
    return answer_key(prev)


def answer_key(v: Any) -> Any:
    """A comparable identity of an answer (two programs agree when their keys are equal)."""
    if isinstance(v, PointValue):
        return ("point", v.object_id, v.point)
    if isinstance(v, OptionValue):
        return ("option", v.options[v.correct])
    if isinstance(v, NumberValue):
        return ("number", round(v.value, 9))
    if isinstance(v, frozenset):
        return ("set", tuple(sorted(v))) if len(v) != 1 else ("object", next(iter(v)))
    if isinstance(v, (int, np.integer)) and not isinstance(v, bool):
        return ("object", int(v))
    return ("value", v)


def degenerate_steps(t: Template, env: dict[str, Any], ctx: Context) -> list[int]:
    """Indices of counted steps whose removal leaves the answer unchanged (empty = the question is sound)."""
    full = answer_key(env[t.steps[-1].name])
    bad = []
    steps = t.steps
    ctx = Context(ctx.idx, ctx.rng, ctx.second, prune=False)  # one replay context for every dropped step
    for st in steps:
        impl = st.impl
        if not impl.droppable:
            continue
        k = st.index
        if k + 1 == len(steps) and impl.drop_to == "none":
            continue  # dropping the yes/no step that is the answer leaves no answer at all (replay: "empty")
        if (
            impl.chain
            and k + 2 == len(steps)
            and steps[-1].impl.locates
            and "of" not in steps[-1].args
            and st.args.get("in") is None
        ):
            # dropping the step that feeds the final locate (a set step, superlative or ordinal) hands locate
            # this step's input set; unless that set is a single object the replay has no answer (not_unique),
            # so it cannot be degenerate
            before = env[steps[k - 1].name] if k > 0 else None
            if not isinstance(before, frozenset):
                before = ctx.idx.all  # what the step reads as its input
            if len(before) != 1:
                continue
        try:
            alt = replay(t, env, ctx, drop=st.index)
        except Reject:
            continue
        if alt == full:
            bad.append(st.index)
    return bad
