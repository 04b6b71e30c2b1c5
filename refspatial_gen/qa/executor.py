"""Run a compiled template program against one frame: bind slots by search, execute typed steps.

Why a search with pruning: most random bindings of a template fail (the relation does not hold, the
result is empty or not unique). Binding slots in the order the program first needs them and running each
step as soon as its slots are bound cuts a failing branch at the first step that fails, so the engine
tries many bindings per millisecond. Every intermediate result is kept for the trace and the checks.
"""

from __future__ import annotations

import math
from itertools import product
from dataclasses import dataclass
from typing import Any, Callable

import numpy as np

from refspatial_gen.core.model import FreeSpaceRegion
from refspatial_gen.qa import ops
from refspatial_gen.qa.index import NO_FACT, Reject, SceneIndex
from refspatial_gen.qa.sample_rng import SampleRng
from refspatial_gen.qa.templates import Ref, Step, Template

TURN_MARGIN = math.radians(5.0)  # a camera turn smaller than this between two views is not asked about


@dataclass(frozen=True)
class PointValue:
    point: tuple[float, float]
    object_id: int | None = None
    region: FreeSpaceRegion | None = None


@dataclass(frozen=True)
class OptionValue:
    options: tuple  # object ids, or words ("left", "right")
    correct: int
    marks: bool = False


@dataclass(frozen=True)
class NumberValue:
    value: float  # SI: metres or radians
    quantity: str


@dataclass
class Context:
    """What a program may read besides the frame's index: the other frame of a multi-view pair."""

    idx: SceneIndex
    rng: "np.random.Generator | SampleRng"  # generation passes the sample's SampleRng
    second: SceneIndex | None = None
    prune: bool = True  # early-pruning bounds on (off when replaying a program for the degeneracy check)


def resolve(ref: Ref, env: dict[str, Any], prev: Any, idx: SceneIndex) -> Any:
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


def _set_in(st: Step, env: dict, prev: Any, idx: SceneIndex) -> frozenset:
    r = st.args.get("in")
    if r is None:
        return prev if isinstance(prev, frozenset) else idx.all
    return resolve(r, env, prev, idx)


def _single(v: Any) -> int:
    if isinstance(v, frozenset):
        if len(v) != 1:
            raise Reject("not_unique" if v else "empty")
        return next(iter(v))
    return v


def _bounded(st: Step, before: frozenset, out: frozenset, ctx: "Context") -> frozenset:
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


def _binary_args(rel: str, x: int, y: int, anchor: int | None) -> tuple:
    return (x, y) if rel not in ops.ANCHORED else (x, y, anchor)


def _winner(cands, rel: str, anchor: int | None, idx: SceneIndex) -> int:
    """The one candidate for which rel(x, y[, anchor]) decidedly holds against every other. Undecided
    comparisons between two losers do not matter; if no candidate wins and one was undecided -> margin."""
    cands = sorted(cands)
    if not cands:
        raise Reject("empty")
    if (rel == "close" or rel == "far") and anchor is not None:
        d = idx.distances_to(anchor, cands)
        if d is not None:
            return _nearest_winner(cands, d, rel == "far", idx.distance_margin)
    # a quick elimination pass finds the only possible winner, then it is checked against everyone
    decision = idx.decision
    best = cands[0]
    for y in cands[1:]:
        h = decision(rel, _binary_args(rel, best, y, anchor))
        if h is NO_FACT:
            raise Reject("no_fact")
        if h is False or h is None and decision(rel, _binary_args(rel, y, best, anchor)) is True:
            best = y
    undecided = False
    for y in cands:
        if y == best:
            continue
        h = decision(rel, _binary_args(rel, best, y, anchor))
        if h is NO_FACT:
            raise Reject("no_fact")
        if h is None:
            undecided = True
        elif not h:
            raise Reject("no_winner")
    if undecided:
        raise Reject("margin")
    return best


def _nearest_winner(cands: list, d: list, farthest: bool, margin: float) -> int:
    """_winner for close/far from the distances of the candidates to the anchor: close(x, y, c) holds when
    d(y, c) - d(x, c) > margin (far: the other way round), so the winner is the nearest (farthest) candidate,
    and it wins only if it beats the runner-up by more than the margin. Same answer as the pairwise rule."""
    if len(cands) == 1:
        return cands[0]
    k = max(range(len(d)), key=d.__getitem__) if farthest else min(range(len(d)), key=d.__getitem__)
    best = d[k]
    gap = min((best - v) if farthest else (v - best) for i, v in enumerate(d) if i != k)
    if gap > margin:
        return cands[k]
    raise Reject("margin" if gap >= -margin else "no_winner")


def _op_filter(st: Step, env: dict[str, Any], prev: Any, ctx: Context) -> Any:
    idx = ctx.idx
    a = st.args
    s = _set_in(st, env, prev, idx)
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


def _op_relate(st: Step, env: dict[str, Any], prev: Any, ctx: Context) -> Any:
    idx = ctx.idx
    a = st.args
    s = _set_in(st, env, prev, idx)
    r, r2 = a["relation"], a["anchor"]
    # slot/step references inline (the hottest op; resolve() gives the same values)
    rel = env[r.value] if r.kind == "slot" or r.kind == "step" else resolve(r, env, prev, idx)
    anchor = env[r2.value] if r2.kind == "slot" or r2.kind == "step" else resolve(r2, env, prev, idx)
    out = idx.narrow(rel, anchor, s)
    return _bounded(st, s, out, ctx)


def _op_at(st: Step, env: dict[str, Any], prev: Any, ctx: Context) -> Any:
    idx = ctx.idx
    a = st.args
    s = _set_in(st, env, prev, idx)
    kind, sid, label = resolve(a["spot"], env, prev, idx)
    out = frozenset(x for x in s if idx.holds(kind, (x, sid, label)))
    return _bounded(st, s, out, ctx)


def _op_is_at(st: Step, env: dict[str, Any], prev: Any, ctx: Context) -> Any:
    idx = ctx.idx
    a = st.args
    kind, sid, label = resolve(a["spot"], env, prev, idx)
    return idx.holds(kind, (resolve(a["a"], env, prev, idx), sid, label))


def _op_between(st: Step, env: dict[str, Any], prev: Any, ctx: Context) -> Any:
    idx = ctx.idx
    a = st.args
    s = _set_in(st, env, prev, idx)
    b, c = resolve(a["anchors"], env, prev, idx)
    return _bounded(st, s, idx.between(b, c, s), ctx)


def _op_superlative(st: Step, env: dict[str, Any], prev: Any, ctx: Context) -> Any:
    idx = ctx.idx
    a = st.args
    s = _set_in(st, env, prev, idx)
    rel = resolve(a["relation"], env, prev, idx)
    anchor = resolve(a["anchor"], env, prev, idx) if "anchor" in a else None
    if rel in ops.ANCHORED and anchor is None:
        raise Reject("no_anchor")
    return _winner([x for x in s if x != anchor], rel, anchor, idx)


def _op_ordinal(st: Step, env: dict[str, Any], prev: Any, ctx: Context) -> Any:
    idx = ctx.idx
    a = st.args
    s = sorted(_set_in(st, env, prev, idx))
    rel = resolve(a["relation"], env, prev, idx)
    rank = resolve(a["rank"], env, prev, idx)
    n = len(s)
    if rank > n or n < 2:
        raise Reject("rank")
    wins = {x: 0 for x in s}
    for i, x in enumerate(s):
        for y in s[i + 1:]:
            if idx.holds(rel, (x, y)):
                wins[x] += 1
            else:
                wins[y] += 1
    for x in s:
        if wins[x] == n - rank:
            return x
    raise Reject("rank")


def _op_locate(st: Step, env: dict[str, Any], prev: Any, ctx: Context) -> Any:
    idx = ctx.idx
    a = st.args
    obj = _single(resolve(a.get("of"), env, prev, idx))
    return PointValue(idx.point(obj), obj)


def _op_free_space(st: Step, env: dict[str, Any], prev: Any, ctx: Context) -> Any:
    idx = ctx.idx
    a = st.args
    if "region" in a:
        r = resolve(a["region"], env, prev, idx)
    elif "anchors" in a:
        b, c = resolve(a["anchors"], env, prev, idx)
        r = idx.regions.get(("between", (b, c))) or idx.regions.get(("between", (c, b)))
    else:
        d = resolve(a["direction"], env, prev, idx)
        r = idx.regions.get((d, (resolve(a["anchor"], env, prev, idx),)))
    if r is None:
        raise Reject("no_free_space")
    return PointValue((float(r.point[0]), float(r.point[1])), None, r)


def _op_compare(st: Step, env: dict[str, Any], prev: Any, ctx: Context) -> Any:
    idx = ctx.idx
    a = st.args
    rel = resolve(a["relation"], env, prev, idx)
    x, y = _single(resolve(a["a"], env, prev, idx)), _single(resolve(a["b"], env, prev, idx))
    anchor = resolve(a["anchor"], env, prev, idx) if "anchor" in a else None
    if x == y or (anchor is not None and anchor in (x, y)):
        raise Reject("same_object")
    if rel in ops.ANCHORED:
        if anchor is None:
            raise Reject("no_anchor")
        return idx.holds(rel, (x, y, anchor))
    return idx.holds(rel, (x, y))


def _op_all(st: Step, env: dict[str, Any], prev: Any, ctx: Context) -> Any:
    idx = ctx.idx
    a = st.args
    return all(resolve(a["of"], env, prev, idx))


def _op_measure(st: Step, env: dict[str, Any], prev: Any, ctx: Context) -> Any:
    idx = ctx.idx
    a = st.args
    q = a["quantity"].value
    x = _single(resolve(a.get("of"), env, prev, idx))
    if q == "distance" or q == "angle":
        y = resolve(a["to"], env, prev, idx)
        if x == y:
            raise Reject("same_object")
        if q == "angle" and not (idx.has_front.get(x) and idx.has_front.get(y)):
            raise Reject("no_front")
        idx.holds(q, (x, y))  # an undecided quantity (unknown front...) is not asked
        return NumberValue(idx.value(q, (x, y)), q)
    if q == "depth" or q.startswith("rotation"):
        idx.holds(q, (x,))  # depth of an object spanning a long range, a turn inside the margin
        return NumberValue(idx.value(q, (x,)), q)
    w, _, h = idx.size(x)
    return NumberValue(h if q == "height" else w, q)


def _op_mark(st: Step, env: dict[str, Any], prev: Any, ctx: Context) -> Any:
    idx = ctx.idx
    a = st.args
    s = sorted(i for i in _set_in(st, env, prev, idx) if i in idx.referable)
    n = resolve(a.get("count"), env, prev, idx) or 3
    if len(s) < n:
        raise Reject("too_few")
    pick = ctx.rng.choice(len(s), size=n, replace=False)
    return tuple(s[int(k)] for k in pick)


def _op_choose(st: Step, env: dict[str, Any], prev: Any, ctx: Context) -> Any:
    idx = ctx.idx
    a = st.args
    opts = resolve(a["options"], env, prev, idx)
    rel = resolve(a["relation"], env, prev, idx)
    anchor = resolve(a["anchor"], env, prev, idx) if "anchor" in a else None
    if len(set(opts)) != len(opts) or (anchor is not None and anchor in opts):
        raise Reject("same_object")
    mode = a["mode"].value if "mode" in a else "most"
    if mode == "which" and rel not in ops.ANCHORED:
        if anchor is None:
            raise Reject("no_anchor")
        sat = [i for i, o in enumerate(opts) if idx.holds(rel, (o, anchor))]
        if len(sat) != 1:
            raise Reject("not_unique" if sat else "empty")
        win = sat[0]
    else:
        if rel in ops.ANCHORED and anchor is None:
            raise Reject("no_anchor")
        if rel in ops.PAIRWISE:
            raise Reject("not_ordered")
        win = list(opts).index(_winner(opts, rel, anchor, idx))
    return OptionValue(tuple(opts), win, marks="options" in a and a["options"].kind == "step")


def _op_camera_turn(st: Step, env: dict[str, Any], prev: Any, ctx: Context) -> Any:
    a = st.args
    if ctx.second is None:
        raise Reject("single_view")
    axis = a["axis"].value
    d = camera_turn(ctx.idx, ctx.second, axis)
    if abs(d) < TURN_MARGIN:
        raise Reject("margin")
    words = ops.TURN_AXES[axis]
    return OptionValue(words, 0 if d > 0 else 1)


_OPS = {  # op name -> implementation (qa/ops.py declares the ops and their arguments)
    "filter": _op_filter, "relate": _op_relate, "at": _op_at, "is_at": _op_is_at, "between": _op_between,
    "superlative": _op_superlative, "ordinal": _op_ordinal, "locate": _op_locate, "free_space": _op_free_space,
    "compare": _op_compare, "all": _op_all, "measure": _op_measure, "mark": _op_mark, "choose": _op_choose,
    "camera_turn": _op_camera_turn
}


def run_step(st: Step, env: dict[str, Any], prev: Any, ctx: Context) -> Any:
    """Execute one step (the reference interpreter); raise Reject when the step has no well-defined result."""
    impl = _OPS.get(st.op)
    if impl is None:
        raise ValueError(f"unknown op {st.op}")
    return impl(st, env, prev, ctx)


def camera_turn(first: SceneIndex, second: SceneIndex, axis: str) -> float:
    """Signed turn of the camera from the first view to the second, radians: + = left (horizontal) / up
    (vertical), from the optical axes in the gravity-aligned world frame (z up)."""
    f1 = first.frame.camera.world_from_cam[:3, 2]
    f2 = second.frame.camera.world_from_cam[:3, 2]
    if axis == "horizontal":
        d = math.atan2(f2[1], f2[0]) - math.atan2(f1[1], f1[0])
        return (d + math.pi) % (2 * math.pi) - math.pi
    e1 = math.asin(max(-1.0, min(1.0, f1[2] / np.linalg.norm(f1))))
    e2 = math.asin(max(-1.0, min(1.0, f2[2] / np.linalg.norm(f2))))
    return e2 - e1


# ---------------------------------------------------------------------------------------------- search
def slot_candidates(t: Template, name: str, env: dict[str, Any], ctx: Context) -> list:
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
        return list(s.choices or ops.FREE_KINDS[:4])
    if s.type == "number":
        return list(s.choices or range(s.min, s.max + 1))
    if s.type == "category":
        return [c for c in idx.categories if not s.choices or c in s.choices]
    if s.type == "color":
        return [c for c in idx.colors if not s.choices or c in s.choices]
    if s.type == "surface":
        return [k for k in sorted(idx.surfaces) if (not s.choices or k in s.choices)
                and any(k in v for v in idx.on.values())]
    if s.type == "spot":
        kinds = s.kinds or ops.REGION_KINDS
        return [sp for sp in idx.spots if sp[0] in kinds]
    if s.type == "region":
        kinds = s.kinds or ops.REGION_KINDS
        return [r for r in idx.region_list if r.kind in kinds and r.label]
    return []


def slot_signature(s) -> tuple:
    """What slot_candidates reads of a slot declaration (computed once per declaration)."""
    sig = s.__dict__.get("_signature")
    if sig is None:
        sig = s.__dict__["_signature"] = (s.type, s.choices, s.category, s.has_front, s.min, s.max, s.kinds)
    return sig


_CHAIN_OPS = frozenset({"filter", "relate", "between", "at", "superlative", "ordinal"})
_SET_OPS = frozenset({"filter", "relate", "between", "at"})


def answer_chain(t: Template) -> list[bool]:
    """Per step: is the answer object certainly a member of this step's output set? True for the set steps
    of a chain that ends in `locate` of its input, where every later step narrows its predecessor's output
    (no `in` of its own). The search uses it to drop a branch as soon as no answer it can reach would pass
    the answer-position balance (generate.Balancer), instead of finding each such answer and rejecting it."""
    steps = t.steps
    n = len(steps)
    flags = [False] * n
    if n < 2 or steps[-1].op != "locate" or steps[-1].args.get("of") is not None:
        return flags
    # the answer is the one member of step n-2's output (or that step's object, for superlative/ordinal)
    for j in range(n - 2, -1, -1):
        op = steps[j].op
        if op in _SET_OPS:
            flags[j] = True
        elif not (j == n - 2 and op in _CHAIN_OPS):
            break
        # step j's input set holds the answer: the previous step's output, when step j reads no `in` of its own
        if steps[j].args.get("in") is not None:
            break
    return flags


def search_plan(t: Template) -> list[tuple]:
    """Per step, computed once per template: the step, the slots it binds, which of those are objects, how
    often it is retried, its compiled function, and whether its output set holds the answer (answer_chain)."""
    plan = t.__dict__.get("_search_plan")
    if plan is None:
        from refspatial_gen.qa.compiled import compiled

        objslots = {n for n, s in t.slots.items() if s.type in ("object", "anchor")}
        plan = t.__dict__["_search_plan"] = [
            (st, st.binds, [k for k, nm in enumerate(st.binds) if nm in objslots], 3 if st.op == "mark" else 1, fn,
             on_chain) for st, fn, on_chain in zip(t.steps, compiled(t), answer_chain(t))]
    return plan


class Search:
    """Depth-first binding of a template's slots with a work budget; yields complete instances.

    Each slot's candidates are shuffled once per search (the sample's generator); object slots must bind
    distinct objects. Every executed step costs one unit of budget.
    """

    def __init__(self, t: Template, ctx: Context, budget: int, answers: frozenset | None = None) -> None:
        """`answers`: the objects the caller would accept as the answer (None = any); a branch whose output
        set on the answer chain (answer_chain) holds none of them is dropped ("balance")."""
        self.t, self.ctx, self.budget, self.answers = t, ctx, budget, answers
        self.rejects: dict[str, int] = {}
        self._cands: dict[str, list] = {}
        self._plan = search_plan(t)
        self._lists: list[list | None] = [None] * len(self._plan)

    def candidates(self, name: str) -> list:
        c = self._cands.get(name)
        if c is None:
            # the unshuffled list depends only on the slot's declaration and the frame: kept on the frame's
            # index under the declaration's signature, so templates declaring the same slot share it
            memo = self.ctx.idx.slot_memo
            mk = slot_signature(self.t.slots[name])
            base = memo.get(mk)
            if base is None:
                base = memo[mk] = tuple(slot_candidates(self.t, name, {}, self.ctx))
            if len(base) < 2:
                base = list(base)
            elif isinstance(self.ctx.rng, SampleRng):
                base = self.ctx.rng.shuffled(base)
            else:  # a numpy Generator (tests and callers outside generation)
                base = [base[k] for k in self.ctx.rng.permutation(len(base))]
            c = self._cands[name] = base
        return c

    def instances(self):
        """Every instance the search reaches, in search order (for tests; generation uses `first`)."""
        found: list[dict] = []

        def collect(env: dict) -> None:
            found.append(dict(env))
        self.first(collect)
        return iter(found)

    def first(self, accept: Callable[[dict], Any]) -> Any:
        """Walk the bindings in search order and call `accept(env)` on each complete instance; return the first
        result that is not None (None when the budget or the space runs out). `env` is the search's own
        dict: accept must copy what it keeps. Plain recursion with a callback, not nested generators: a
        generator per level and a `yield from` chain per instance cost more than the steps themselves."""
        self._accept = accept
        return self._walk(0, {}, None, frozenset())

    def _walk(self, i: int, env: dict[str, Any], prev: Any, used: frozenset) -> Any:
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


def replay(t: Template, env: dict[str, Any], ctx: Context, drop: int | None = None,
           reuse_prefix: bool = True) -> Any:
    """Re-run the program with the slots of `env`, optionally with step `drop` removed; returns the answer.

    Removing a set-narrowing step passes its input through; removing a superlative/ordinal leaves the
    input set (an answer only if it holds one object); removing a compare drops it from its `all`, or
    leaves no answer when it was the answer itself. Raises Reject when there is no answer.
    With `reuse_prefix`, the steps before `drop` are not re-run: their results are the instance's own (a step
    depends only on the slots and earlier steps, and pruning only adds rejections, never changes a value).
    """
    from refspatial_gen.qa.compiled import compiled

    if ctx.prune:
        ctx = Context(ctx.idx, ctx.rng, ctx.second, prune=False)
    prev = None
    steps, fns = t.steps, compiled(t)
    if reuse_prefix and drop:
        # every step reads only slots and earlier steps, and each step from `drop` on is rewritten before it is
        # read: the instance's own dict is the right starting point
        local = dict(env)
        prev = env[steps[drop - 1].name]
        steps, fns = steps[drop:], fns[drop:]
    else:
        local = {k: v for k, v in env.items() if k in t.slots}
    for st, fn in zip(steps, fns):
        if st.index == drop:
            if st.op in ("relate", "between", "at"):
                val = _set_in(st, local, prev, ctx.idx)
            elif st.op in ("superlative", "ordinal"):
                val = _set_in(st, local, prev, ctx.idx)
            elif st.op in ("compare", "is_at"):
                val = None
            else:
                raise Reject("not_droppable")
        elif st.op == "all":
            vals = [local[r.value] for r in st.args["of"].value]
            vals = [v for v in vals if v is not None]
            if not vals:
                raise Reject("empty")
            val = all(vals)
        elif st.op == "mark":
            val = env[st.name]  # the drawn marks are part of the question
        else:
            val = fn(local, prev, ctx)  # the compiled step (the same result as run_step; a test pins it)
            if val.__class__ is Reject:
                raise Reject(val.reason)  # a fresh exception: the returned one may be a shared constant
        if val is None and st is t.steps[-1]:
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
        if st.op not in ops.DROPPABLE:
            continue
        k = st.index
        if k + 1 == len(steps) and st.op in ("compare", "is_at"):
            continue  # dropping the yes/no step that is the answer leaves no answer at all (replay: "empty")
        if (st.op in _CHAIN_OPS and k + 2 == len(steps) and steps[-1].op == "locate" and "of" not in steps[-1].args
                and st.args.get("in") is None):
            # dropping the step that feeds the final locate (a set step, superlative or ordinal) hands locate
            # this step's input set; unless that set is a single object the replay has no answer (not_unique),
            # so it cannot be degenerate
            before = env[steps[k - 1].name] if k > 0 else None
            if not isinstance(before, frozenset):
                before = ctx.idx.all  # what _set_in hands the step
            if len(before) != 1:
                continue
        try:
            alt = replay(t, env, ctx, drop=st.index)
        except Reject:
            continue
        if alt == full:
            bad.append(st.index)
    return bad
