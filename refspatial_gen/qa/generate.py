"""generate_qa: pick families and templates, search bindings, run every check, render QA pairs.

Why the checks live here and not in templates: a recipe author cannot forget them. Every QA pair has
unique references (named objects by their graph phrase, described targets resolve to exactly one
object), no degenerate step (dropping any counted step changes the answer), no relation inside its
margin (an undecided fact rejects the binding), and balanced answers (yes/no drawn to even out,
letters shuffled, answer points spread over image quadrants by rejection).
"""

from __future__ import annotations

from collections import OrderedDict

from typing import Any, NamedTuple

import numpy as np

from refspatial_gen.core.model import Frame, KeyStep, QAPair, SceneGraph
from refspatial_gen.qa import lexicon, ops
from refspatial_gen.qa.config import QAConfig
from refspatial_gen.qa.executor import (Context, NumberValue, OptionValue, PointValue, Search, answer_chain,
                                        degenerate_steps,
                                        slot_candidates)
from refspatial_gen.qa.index import Reject, SceneIndex
from refspatial_gen.qa.sample_rng import SampleRng
from refspatial_gen.qa.render import (LETTERS, fmt_angle, fmt_choices, fmt_length, fmt_points, fmt_trace,
                                      fmt_turn, round_key)
from refspatial_gen.qa.templates import Ref, Template
from refspatial_gen.qa.text import Seq, parse, placeholders, render

_MISS = object()
CHECKS = ("unique_references", "nondegenerate", "outside_margin", "balanced")
class _IndexCache:
    """The few most recent graph -> SceneIndex entries. Bounded on purpose: a WeakKeyDictionary never freed
    anything here, because each index refers to its own graph (memory grew ~6 MB per scene in a worker)."""

    def __init__(self, size: int = 8) -> None:
        self._d: "OrderedDict[int, tuple[SceneGraph, SceneIndex]]" = OrderedDict()
        self.size = size

    def get(self, graph: SceneGraph) -> "SceneIndex | None":
        e = self._d.get(id(graph))
        return e[1] if e is not None and e[0] is graph else None

    def __setitem__(self, graph: SceneGraph, idx: "SceneIndex") -> None:
        self._d[id(graph)] = (graph, idx)
        self._d.move_to_end(id(graph))
        while len(self._d) > self.size:
            self._d.popitem(last=False)

    def pop(self, graph: SceneGraph, default=None):
        e = self._d.pop(id(graph), None)
        return default if e is None or e[0] is not graph else e[1]


_INDEX_CACHE = _IndexCache()
_PARSED: dict[str, Seq] = {}


def scene_index(frame: Frame, graph: SceneGraph) -> SceneIndex:
    """The cached lookup index of a (frame, graph) pair (built once per graph object), for callers that query
    the same graph many times (tests, the warm-index bench); generate_qa builds its own unless given one."""
    idx = _INDEX_CACHE.get(graph)
    if idx is None or idx.frame is not frame:
        idx = SceneIndex(frame, graph)
        _INDEX_CACHE[graph] = idx
    return idx


def _seq(text: str) -> Seq:
    s = _PARSED.get(text)
    if s is None:
        s = _PARSED[text] = parse(text)
    return s


class Balancer:
    """Per-call counters that keep answers even: yes/no, answer letters and answer-point quadrants."""

    def __init__(self, slack: int) -> None:
        self.slack = slack
        self.yes_no = [0, 0]
        self.quadrants = [0, 0, 0, 0]
        self._allowed: dict[tuple, frozenset | None] = {}

    def want_bool(self, rng: SampleRng) -> bool:
        if self.yes_no[0] != self.yes_no[1]:
            return self.yes_no[0] < self.yes_no[1]  # index 0 counts "yes"
        return bool(rng.integers(2))

    @staticmethod
    def quadrant(p: tuple[float, float]) -> int:
        return int(p[0] >= 0.5) + 2 * int(p[1] >= 0.5)

    def point_ok(self, p: tuple[float, float]) -> bool:
        return self.quadrants[self.quadrant(p)] <= min(self.quadrants) + self.slack

    def allowed_answers(self, idx: SceneIndex) -> frozenset | None:
        """Objects whose answer point the quadrant balance accepts now (None: every object), so the search can
        drop branches that could only reach rejected answers."""
        key = (id(idx), tuple(self.quadrants))
        hit = self._allowed.get(key, _MISS)
        if hit is _MISS:
            low = min(self.quadrants) + self.slack
            if max(self.quadrants) <= low:
                hit = None
            else:
                q = self.quadrants
                hit = frozenset(i for i, p in idx.answer_points.items() if q[self.quadrant(p)] <= low)
            self._allowed[key] = hit
        return hit

    def add(self, answer: Any) -> None:
        if isinstance(answer, bool):
            self.yes_no[0 if answer else 1] += 1
        elif isinstance(answer, PointValue):
            self.quadrants[self.quadrant(answer.point)] += 1


def generate_qa(frames: list[Frame], graphs: list[SceneGraph], rng: np.random.Generator,
                config: QAConfig, indexes: list[SceneIndex] | None = None) -> list[QAPair]:
    """Up to `config.max_per_sample` checked QA pairs for one sample (one frame or a multi-view group).

    The lookup indexes are built for this call and freed with it (a run uses each graph in one sample only;
    keeping them would only give the garbage collector more to scan). Callers that ask several times of the
    same graphs (tests, the warm-index bench) pass `indexes` (scene_index) to reuse them.
    """
    if len(frames) != len(graphs):
        raise ValueError(f"{len(frames)} frames but {len(graphs)} graphs")
    if indexes is not None and (len(indexes) != len(frames)
                                or any(i.frame is not f or i.graph is not g for i, f, g in zip(indexes, frames, graphs))):
        raise ValueError("indexes must be the SceneIndex of each (frame, graph), in order")
    idxs = indexes or [SceneIndex(f, g) for f, g in zip(frames, graphs)]
    return _generate(frames, idxs, rng, config)


def _generate(frames: list[Frame], idxs: list[SceneIndex], sample_rng: np.random.Generator,
              config: QAConfig) -> list[QAPair]:
    rng = SampleRng(sample_rng)  # template QA draws from a fast generator seeded by the sample's
    pairs = [(i, j) for i in range(len(frames)) for j in range(len(frames))
             if i != j and frames[i].scene_id and frames[i].scene_id == frames[j].scene_id]
    bal = Balancer(config.point_slack)
    out: list[QAPair] = []
    seen: set = set()
    per_family: dict[str, int] = {}
    mv_count = 0
    exhausted: set[int] = set()
    fams = [f for f in config.families if f.weight > 0 and f.templates]
    views = [Context(ix, rng) for ix in idxs]  # single-view contexts (read-only: shared by the attempts)
    capped = any(f.max_per_sample is not None for f in fams)
    usable, weights = fams, [f.weight for f in fams]
    for _attempt in range(config.attempts + config.max_per_sample):
        if len(out) >= config.max_per_sample or not fams:
            break
        if capped:
            usable = [f for f in fams if f.max_per_sample is None or per_family.get(f.name, 0) < f.max_per_sample]
            weights = [f.weight for f in usable]
        if not usable:
            break
        fam = usable[_pick(weights, rng)]
        temps, tw = _family_choices(fam, config, exhausted, bool(pairs) and mv_count < config.multiview_pairs)
        if not temps or sum(tw) <= 0:
            continue
        t = temps[_pick(tw, rng)]
        if _is_multiview(t):
            i, j = pairs[int(rng.integers(len(pairs)))]
            ctx = Context(idxs[i], rng, idxs[j])
            fids = [frames[i].frame_id, frames[j].frame_id]
        else:
            i = int(rng.integers(len(frames)))
            ctx = views[i]
            fids = [frames[i].frame_id]
        qid = f"{frames[0].frame_id}:{len(out):02d}"
        qa = _instantiate(t, ctx, rng, config, bal, seen, fids, qid, view=i)
        if qa is None and t.answer_type == ops.BOOL:  # the other answer may exist (the balancer catches up)
            qa = _instantiate(t, ctx, rng, config, bal, seen, fids, qid, flip=True, view=i)
        if qa is None:
            exhausted.add(id(t))  # no binding passed in this sample: do not spend more attempts on it
            continue
        out.append(qa)
        per_family[fam.name] = per_family.get(fam.name, 0) + 1
        if _is_multiview(t):
            mv_count += 1
    if config.point_depth:  # built-in camera-frame point/depth questions (work on frames without objects)
        from refspatial_gen.qa.pointdepth import point_depth_qa
        out += point_depth_qa(frames, sample_rng, min(config.point_depth, config.max_per_sample - len(out)), len(out))
    return out


_FAMILY_PLANS: dict[tuple[int, int], tuple] = {}


def _family_choices(fam: Any, config: QAConfig, exhausted: set[int], multiview: bool) -> tuple[list, list]:
    """The family's templates a draw may pick now, with their weights (template weight x step mix): those with
    positive weight, not exhausted in this sample, multi-view ones only when a view pair is still wanted.
    The unfiltered lists are computed once per (family, config)."""
    key = (id(fam), id(config))
    plan = _FAMILY_PLANS.get(key)
    if plan is None or plan[0] is not fam or plan[1] is not config:
        mix = config.step_mix
        temps = [t for t in fam.templates if t.weight > 0]
        multi = [_is_multiview(t) for t in temps]
        weights = [t.weight * mix.get(t.n_steps, 1.0 if not mix else 0.0) for t in temps]
        single = [k for k, m in enumerate(multi) if not m]
        plan = (fam, config, temps, weights, multi, frozenset(id(t) for t in temps),
                ([temps[k] for k in single], [weights[k] for k in single]) if any(multi) else (temps, weights))
        if len(_FAMILY_PLANS) > 256:
            _FAMILY_PLANS.clear()
        _FAMILY_PLANS[key] = plan
    _, _, temps, weights, multi, members, single_view = plan
    if not exhausted or exhausted.isdisjoint(members):
        return (temps, weights) if multiview else single_view
    keep = [k for k, t in enumerate(temps) if id(t) not in exhausted and (multiview or not multi[k])]
    return [temps[k] for k in keep], [weights[k] for k in keep]


def _pick(weights: list[float], rng: SampleRng) -> int:
    """Index drawn with probability proportional to its weight (cheaper than rng.choice with p=)."""
    total = sum(weights)
    r = rng.random() * total
    acc = 0.0
    for i, w in enumerate(weights):
        acc += w
        if r < acc and w > 0:
            return i
    return max(i for i, w in enumerate(weights) if w > 0)


class _Needs(NamedTuple):
    """What generation asks of a template on every attempt, read from its program once."""

    multiview: bool  # a camera_turn step: needs a second view
    spot: bool  # an `at` step: some object must be at a corner or edge
    between: int  # the most objects any `between` step must keep (its search bound; 0 = no such step)
    between_region: bool  # free space between two anchors: the graph must have such a region
    slot_names: tuple  # sorted: the dedup key reads the instance's slots in this order


def _needs(t: Template) -> _Needs:
    v = t.__dict__.get("_needs")
    if v is None:
        steps = t.steps
        v = t.__dict__["_needs"] = _Needs(
            any(st.op == "camera_turn" for st in steps), any(st.op == "at" for st in steps),
            max([max(st.min_out, 1) for st in steps if st.op == "between"] or [0]),
            any(st.op == "free_space" and "anchors" in st.args for st in steps), tuple(sorted(t.slots)))
    return v


def _is_multiview(t: Template) -> bool:
    return _needs(t).multiview


def _instantiate(t: Template, ctx: Context, rng: SampleRng, config: QAConfig, bal: Balancer,
                 seen: set, frame_ids: list[str], qa_id: str, flip: bool = False, view: int = 0) -> QAPair | None:
    """One checked QA pair of template t on ctx's frame (`view`: that frame's position in the sample), or None."""
    needs = _needs(t)
    if needs.spot and not ctx.idx.has_true_spot:
        return None  # an `at` step keeps objects at a corner/edge; with none anywhere every binding is empty
    if needs.between and ctx.idx.largest_between_row < needs.between:
        return None  # a `between` step must keep that many objects; no anchor pair has that many between it
    if needs.between_region and not ctx.idx.has_between_region:
        return None  # free space between two anchors, and the graph has no such region
    want = bal.want_bool(rng) if t.answer_type == ops.BOOL else None
    if flip and want is not None:
        want = not want
    last = t.steps[-1].name
    slots = needs.slot_names
    is_obj = t.answer_type == ops.OBJECT
    idx = ctx.idx

    def accept(env: dict) -> QAPair | None:
        ans = env[last]
        if want is not None and ans is not want:
            return None
        if is_obj:
            ans = PointValue(idx.point(ans), ans)
        if isinstance(ans, PointValue):
            if not bal.point_ok(ans.point):
                return None
            if ans.object_id is not None and not idx.point_in_mask(ans.object_id, ans.point):
                return None
        # the checks are independent filters: the cheap ones first, the replays (degeneracy) last
        key = (t.family, t.name, tuple([(k, _hashable(env[k])) for k in slots if k in env]))
        if key in seen:
            return None
        if degenerate_steps(t, env, ctx):
            return None
        try:
            extra = _bind_text_only(t, env, ctx)
            qa = _build(t, {**env, **extra}, ans, ctx, rng, frame_ids, qa_id, view)
        except Reject:
            return None
        seen.add(key)
        bal.add(env[last] if t.answer_type == ops.BOOL else ans)
        return qa
    answers = bal.allowed_answers(idx) if any(answer_chain(t)) else None
    return Search(t, ctx, config.budget, answers).first(accept)


def _one(v: Any) -> int:
    if isinstance(v, frozenset):
        if len(v) != 1:
            raise Reject("not_unique")
        return int(next(iter(v)))
    return int(v)


def _hashable(v: Any) -> Any:
    if isinstance(v, (int, str, float, bool, tuple)):
        return v
    return (type(v).__name__, id(v))


def _bind_text_only(t: Template, env: dict, ctx: Context) -> dict:
    out = {}
    for name in t.unbound:
        c = slot_candidates(t, name, env, ctx)
        if not c:
            raise Reject("no_candidate")
        out[name] = c[int(ctx.rng.integers(len(c)))]
    return out


# ------------------------------------------------------------------------------------------ rendering
def _surface_name(ctx: Context, sid: str) -> str:
    s = ctx.idx.surfaces.get(sid)
    if s is None:
        return f"the {sid}"
    return s.name or f"the {s.kind}"


def spot_phrase(idx: SceneIndex, spot: tuple[str, str, str], form: str = "") -> str:
    """("corner", "table", "far-left") -> "the far-left corner of the table"; edges carry their own noun."""
    kind, sid, label = spot
    s = idx.surfaces.get(sid)
    sname = (s.name or f"the {s.kind}") if s is not None else f"the {sid}"
    if form == "surface":
        return sname
    lab = label if label.endswith(kind) else f"{label} {kind}"
    if form == "label":
        return lab
    return f"the {lab} of {sname}"


def _plural(word: str) -> str:
    if word.endswith(("s", "x", "ch", "sh")):
        return word + "es"
    if word.endswith("y") and word[-2:-1] not in "aeiou":
        return word[:-1] + "ies"
    return word + "s"


class _Renderer:
    def __init__(self, t: Template, env: dict, ctx: Context, rng: SampleRng, choices: str,
                 instruction: str) -> None:
        self.t, self.env, self.ctx, self.rng = t, env, ctx, rng
        self.choices, self.instruction = choices, instruction

    def __call__(self, name: str) -> str:
        base, _, form = name.partition(".")
        if base == "choices":
            return self.choices
        if base == "instruction":
            return self.instruction
        s = self.t.slots[base]
        v = self.env[base]
        idx = self.ctx.idx
        if s.type in ("object", "anchor"):
            if form == "category":
                return idx.category[v]
            if form == "color":
                return idx.color.get(v) or ""
            return idx.phrase[v]
        if s.type == "relation":
            f = form or "prep"
            seq = s.phrases.get(v, {}).get(f)
            if seq is None:
                text = lexicon.RELATION_FORMS.get(v, {}).get(f)
                if text is None:
                    raise Reject("no_wording")
                seq = _seq(text)
            return render(seq, self, self.rng, sentence=False)
        if s.type == "direction":
            seq = s.phrases.get(v, {}).get("") or _seq(lexicon.DIRECTION_FORMS.get(v, v.replace("_", " ")))
            return render(seq, self, self.rng, sentence=False)
        if s.type == "number":
            return str(v) if form == "value" else lexicon.ORDINALS.get(v, f"{v}th")
        if s.type == "category":
            return _plural(v) if form == "plural" else v
        if s.type == "color":
            return v
        if s.type == "surface":
            return _surface_name(self.ctx, v)
        if s.type == "region":
            return _surface_name(self.ctx, v.surface_id) if form == "surface" else v.label
        if s.type == "spot":
            return spot_phrase(self.ctx.idx, v, form)
        return str(v)


def _ref_json(ref: Ref | None, env: dict, t: Template, idx: SceneIndex) -> Any:
    if ref is None:
        return {"step": "prev"}
    if ref.kind == "list":
        return [_ref_json(r, env, t, idx) for r in ref.value]
    if ref.kind == "all":
        return "all"
    if ref.kind == "step":
        return {"step": ref.value}
    if ref.kind == "literal":
        return ref.value
    v = env[ref.value]
    s = t.slots[ref.value]
    if s.type in ("object", "anchor"):
        return {"slot": ref.value, "object": int(v), "phrase": idx.phrase[v]}
    if s.type == "spot":
        return {"slot": ref.value, "spot": list(v)}
    if s.type == "region":
        return {"slot": ref.value, "region": {"surface_id": v.surface_id, "kind": v.kind,
                                              "anchors": list(v.anchors), "label": v.label}}
    return v


def _out_json(v: Any) -> Any:
    if v.__class__ is frozenset:
        return sorted(map(int, v))
    if isinstance(v, PointValue):
        d: dict[str, Any] = {"point": [round(v.point[0], 3), round(v.point[1], 3)]}
        if v.object_id is not None:
            d["object"] = int(v.object_id)
        if v.region is not None:
            d["region"] = {"surface_id": v.region.surface_id, "kind": v.region.kind,
                           "anchors": list(v.region.anchors), "label": v.region.label}
        return d
    if isinstance(v, OptionValue):
        return {"options": [int(o) if not isinstance(o, str) else o for o in v.options], "correct": v.correct}
    if isinstance(v, NumberValue):
        return {"value": round(v.value, 6), "quantity": v.quantity}
    if isinstance(v, tuple):
        return [int(x) for x in v]
    if isinstance(v, (bool, str)):
        return v
    if isinstance(v, (int, np.integer)):
        return int(v)
    return v


def _arg_plan(t: Template, st: Any) -> tuple:
    """How _build writes each argument of a step into the program record: (key, mode, payload) with mode
    0 = a constant, 1 = a step reference, 2 = an object slot, 3 = anything else (through _ref_json)."""
    out = []
    for k, r in st.args.items():
        if r.kind == "all":
            out.append((k, 0, "all"))
        elif r.kind == "literal" and isinstance(r.value, (str, int, float, bool)):
            out.append((k, 0, r.value))
        elif r.kind == "step":
            out.append((k, 1, r.value))
        elif r.kind == "slot" and t.slots[r.value].type in ("object", "anchor"):
            out.append((k, 2, r.value))
        else:
            out.append((k, 3, r))
    return tuple(out)


class _BuildPlan(NamedTuple):
    """What _build needs from a template that does not depend on the instance (computed once)."""

    relations: frozenset  # relation ids fixed by the program (literal relations, between, quantities...)
    relation_slots: tuple  # relation slots: their bound value is a relation of the question
    region_refs: tuple  # region slots of free_space steps: their kind is a relation
    spot_refs: tuple  # spot slots of at / is_at steps: their kind (corner, edge) is a relation
    program: tuple  # per step: (step, its args, implicit "in" (prev step name, "" = all, None = none),
    #                 implicit "of" ((prev step name,) or None))


def _build_plan(t: Template) -> _BuildPlan:
    plan = t.__dict__.get("_build_plan")
    if plan is not None:
        return plan
    rel = set(t.relations)
    regions, spots = [], []
    for st in t.steps:
        if st.op == "between":
            rel.add("between")
        elif st.op == "free_space":
            rel.add("free_space")
            if "region" in st.args:
                regions.append(st.args["region"].value)
        elif st.op in ("at", "is_at"):
            spots.append(st.args["spot"].value)
        elif st.op == "measure":
            rel.add(ops.QUANTITIES[st.args["quantity"].value][1])
        elif st.op == "camera_turn":
            rel.add("rotation_" + st.args["axis"].value)
    program = []
    prev_name = None
    for st in t.steps:
        default_in = None
        if st.args.get("in") is None and ops.OPS[st.op].args.get("in") is not None:
            default_in = prev_name or ""
        default_of = (prev_name,) if st.op in ("locate", "measure") and "of" not in st.args else None
        program.append((st, _arg_plan(t, st), default_in, default_of))
        prev_name = st.name
    plan = t.__dict__["_build_plan"] = _BuildPlan(
        frozenset(rel), tuple(n for n, s in t.slots.items() if s.type == "relation"), tuple(regions), tuple(spots),
        tuple(program))
    return plan


def _build(t: Template, env: dict, ans: Any, ctx: Context, rng: SampleRng, frame_ids: list[str],
           qa_id: str, view: int = 0) -> QAPair:
    """The QA pair's record. `view` is the asked frame's position in the sample's frames: drawn marks name it,
    so the exporter and the preview draw them on that image."""
    idx = ctx.idx
    plan = _build_plan(t)
    relations = set(plan.relations)
    for name in plan.relation_slots:
        if name in env:
            relations.add(env[name])
    for name in plan.region_refs:
        relations.add(env[name].kind)
    for name in plan.spot_refs:
        relations.add(env[name][0])
    # -------- answer and choices
    choices_text = ""
    targets: list[int] = []
    raw = env[t.steps[-1].name]
    if isinstance(ans, PointValue):
        answer = fmt_points([ans.point])
        if ans.region is not None:
            r = ans.region
            poly, world = idx.region_rounded(r)
            struct = {"kind": "region", "points": [list(ans.point)],
                      "region": {"surface_id": r.surface_id, "kind": r.kind, "anchors": list(r.anchors),
                                 "label": r.label, "z": round(float(r.z), 6),
                                 "polygon_xy": [list(p) for p in poly], "point_world": list(world)}}
            targets = [int(a) for a in r.anchors if isinstance(a, (int, np.integer))]
        else:
            struct = {"kind": "points", "points": [list(ans.point)], "object_ids": [int(ans.object_id)]}
            targets = [int(ans.object_id)]
    elif isinstance(raw, bool):
        order = ["yes", "no"] if rng.integers(2) == 0 else ["no", "yes"]
        k = order.index("yes" if raw else "no")
        choices_text = fmt_choices(order)
        answer = f"({LETTERS[k]})" if rng.integers(2) == 0 else f"({LETTERS[k]}) {order[k]}"
        struct = {"kind": "choice", "options": order, "letter": LETTERS[k], "answer": order[k]}
        targets = sorted({_one(env[r.value]) for st in t.steps if st.op in ("compare", "is_at")
                          for r in (st.args["a"], st.args.get("b")) if r is not None and r.kind in ("slot", "step")})
    elif isinstance(raw, OptionValue):
        n = len(raw.options)
        if raw.marks:
            perm = list(range(n))  # marks are already in random order; their labels follow it
        else:
            perm = [int(x) for x in rng.permutation(n)]
        opts = [raw.options[p] for p in perm]
        k = perm.index(raw.correct)
        if raw.marks:
            texts = ["" for _ in opts]
        else:
            texts = [o if isinstance(o, str) else idx.phrase[o] for o in opts]
        choices_text = fmt_choices(texts)
        answer = f"({LETTERS[k]})" if (raw.marks or rng.integers(2) == 0) else f"({LETTERS[k]}) {texts[k]}"
        struct = {"kind": "choice", "options": texts, "letter": LETTERS[k],
                  "answer": texts[k] if texts[k] else LETTERS[k]}
        if not isinstance(opts[0], str):
            struct["option_ids"] = [int(o) for o in opts]
            targets = [int(opts[k])]
        if raw.marks:
            style = next(st.args["style"].value if "style" in st.args else "box" for st in t.steps if st.op == "mark")
            struct["style"] = style
            struct["marks"] = [{"label": LETTERS[i], "object_id": int(o), "style": style, "view": view,
                                "box": [round(float(x), 1) for x in idx.objects[o].bbox2d]
                                if idx.objects[o].bbox2d is not None else None,
                                "point": list(idx.point(o))} for i, o in enumerate(opts)]
    elif isinstance(raw, NumberValue):
        q = raw.quantity
        kind = ops.QUANTITIES[q][2]
        if kind == "length":
            answer, unit = fmt_length(raw.value), "m"
        elif kind == "angle":
            answer, unit = fmt_angle(raw.value), "rad"
        else:
            answer, unit = fmt_turn(raw.value, q.split("_")[1]), "rad"
        struct = {"kind": "number", "value": round(raw.value, 6), "unit": unit, "quantity": q}
        targets = sorted({_one(env[r.value]) for st in t.steps if st.op == "measure"
                          for k2, r in st.args.items() if k2 in ("of", "to") and r.kind in ("slot", "step")})
        if not targets:
            prev = env[t.steps[-2].name] if len(t.steps) > 1 else None
            if isinstance(prev, frozenset) and len(prev) == 1:
                prev = next(iter(prev))
            if isinstance(prev, (int, np.integer)):
                targets = [int(prev)]
    else:
        raise Reject("answer_type")
    # -------- question text
    if isinstance(ans, PointValue):
        instr_seq = t.instructions[int(rng.integers(len(t.instructions)))] if t.instructions else \
            _seq(lexicon.POINT_INSTRUCTIONS[int(rng.integers(len(lexicon.POINT_INSTRUCTIONS)))])
    else:
        instr_seq = None
    variant = t.texts[int(rng.integers(len(t.texts)))]
    ph = placeholders(variant)
    rend = _Renderer(t, env, ctx, rng, choices_text, "")
    if instr_seq is not None:
        rend.instruction = render(instr_seq, rend, rng)
    question = render(variant, rend, rng)
    if choices_text and "choices" not in ph:
        question = f"{question} {choices_text}"
    if instr_seq is not None and "instruction" not in ph:
        question = f"{question} {rend.instruction}"
    # -------- key steps and trace
    key_steps = _key_steps(t, env, ans, ctx)
    _check_key_phrases(key_steps, struct, targets, idx)
    trace = fmt_trace(key_steps, answer) if t.n_steps >= 2 else ""
    program = []
    phrase = idx.phrase
    for st, arg_plan, default_in, default_of in plan.program:
        args: dict[str, Any] = {}
        for k, mode, p in arg_plan:
            if mode == 0:
                args[k] = p
            elif mode == 1:
                args[k] = {"step": p}
            elif mode == 2:
                v = env[p]
                args[k] = {"slot": p, "object": int(v), "phrase": phrase[v]}
            else:
                args[k] = _ref_json(p, env, t, idx)
        if default_in is not None:
            args["in"] = {"step": default_in} if default_in else "all"
        if default_of is not None:
            args["of"] = {"step": default_of[0]}
        program.append({"op": st.op, "as": st.name, "args": args, "out": _out_json(env[st.name]),
                        "weight": st.weight})
    checks = list(CHECKS)
    if isinstance(ans, PointValue):
        checks.append("free_point" if ans.region is not None else "point_in_mask")
    return QAPair(qa_id=qa_id, family=t.family, template=f"{t.family}/{t.name}", question=question, answer=answer,
                  answer_struct=struct, relations=sorted(relations), steps=t.n_steps, frame_ids=list(frame_ids),
                  image_size=(idx.W, idx.H), program=program, trace=trace, key_steps=key_steps, checks=checks,
                  targets=targets)


def _check_key_phrases(key_steps: list[KeyStep], struct: dict, targets: list[int], idx: SceneIndex) -> None:
    """Every key step must name its object so a reward function (and `verify`) can find it: a graph phrase, a
    drawn mark, the free space, or, for the final position only, the answer target. An object with no unique
    phrase looked at on the way (e.g. the bottle a `between` step described) cannot be named: Reject."""
    names = idx.phrase_set
    marks = {f"the object marked ({m['label']})" for m in struct.get("marks") or []}
    last = key_steps[-1] if key_steps else None
    for ks in key_steps:
        ph = ks.phrase
        if ph in names or ph in marks or (ks.type == "Position" and ph.startswith("the free space")):
            continue
        if ks is last and ks.type == "Position" and targets:
            continue
        raise Reject("unnamed_key_step")


class _KeyPlan(NamedTuple):
    """What _key_steps reads of one step, resolved once per template."""

    step: Any
    rel_literal: Any  # the relation when the program fixes it
    rel_slot: str | None  # the slot/step holding the relation otherwise
    single: tuple  # env names of single-object arguments (anchor, a, b, of, to), in that order
    lists: tuple  # env names inside list arguments (anchors, options)
    orient_a: str | None  # compare on an orientation relation: its `a` argument
    measure: tuple | None  # (quantity, names of of/to, reads the previous step)
    choose_marks: str | None  # choose over drawn marks: the mark step's name


def _key_plan(t: Template) -> tuple:
    plan = t.__dict__.get("_key_plan")
    if plan is not None:
        return plan
    out = []
    for st in t.steps:
        a = st.args
        r = a.get("relation")
        lit = r.value if r is not None and r.kind == "literal" else None
        slot = r.value if r is not None and r.kind != "literal" else None
        single = tuple(a[k].value for k in ("anchor", "a", "b", "of", "to")
                       if a.get(k) is not None and a[k].kind in ("slot", "step"))
        lists = tuple(x.value for k in ("anchors", "options") if a.get(k) is not None and a[k].kind == "list"
                      for x in a[k].value)
        orient_a = a["a"].value if st.op == "compare" else None
        measure = None
        if st.op == "measure":
            measure = (a["quantity"].value, tuple(a[k].value for k in ("of", "to") if k in a), "of" not in a)
        marks = a["options"].value if st.op == "choose" and a["options"].kind == "step" else None
        out.append(_KeyPlan(st, lit, slot, single, lists, orient_a, measure, marks))
    plan = t.__dict__["_key_plan"] = tuple(out)
    return plan


def _key_steps(t: Template, env: dict, ans: Any, ctx: Context) -> list[KeyStep]:
    """One perceptual step per object the reasoning looks at, in program order, then the answer."""
    idx = ctx.idx
    out: list[KeyStep] = []
    placed: set[str] = set()  # phrases with a Position step (and Size, Orientation below): one of each
    sized_done: set[str] = set()
    oriented: set[str] = set()
    phrase_of = idx.phrase

    def name(o: int) -> str:
        return phrase_of.get(o) or f"the target {idx.category[o]}"

    def pos(o: int, phrase: str | None = None) -> None:
        ph = phrase or phrase_of.get(o) or f"the target {idx.category[o]}"
        if ph not in placed:
            placed.add(ph)
            out.append(KeyStep("Position", ph, idx.key_point(o)))

    def size(o: int) -> None:
        ph = name(o)
        if ph not in sized_done:
            sized_done.add(ph)
            out.append(KeyStep("Size", ph, round_key(idx.size(o))))

    def orient(o: int) -> None:
        ph = name(o)
        if ph not in oriented:
            oriented.add(ph)
            out.append(KeyStep("Orientation", ph, round_key(idx.front_cam(o))))

    size_rels, orient_rels = ops.SIZE_RELATIONS, ops.ORIENTATION_RELATIONS
    final_orient = False
    steps = t.steps
    for kp in _key_plan(t):
        rel = kp.rel_literal if kp.rel_slot is None else env[kp.rel_slot]
        sized = rel in size_rels
        for nm in kp.single:
            o = _one(env[nm])
            pos(o)
            if sized:
                size(o)
        for nm in kp.lists:
            o = env[nm]
            pos(o)
            if sized:
                size(o)
        op = kp.step.op
        if kp.orient_a is not None and rel in orient_rels:
            orient(_one(env[kp.orient_a]))
        if op == "relate" and rel in orient_rels:
            final_orient = True
        if kp.measure is not None:
            q, names, from_prev = kp.measure
            targets = [_one(env[nm]) for nm in names]
            if from_prev:
                prev = env[steps[kp.step.index - 1].name]
                targets.insert(0, next(iter(prev)) if isinstance(prev, frozenset) else prev)
            for o in targets:
                if q in ("height", "width"):
                    size(o)
                elif q == "angle":
                    orient(o)
                else:
                    pos(o)
        if kp.choose_marks is not None:
            for i, o in enumerate(env[kp.choose_marks]):
                pos(o, f"the object marked ({LETTERS[i]})")
                if sized:
                    size(o)
    if isinstance(ans, PointValue):
        if ans.region is not None:
            r = ans.region
            out.append(KeyStep("Position", f"the free space {r.kind.replace('_', ' ')} "
                               + " and ".join(phrase_of.get(a, str(a)) for a in r.anchors if a in phrase_of)
                               if r.kind in ops.FREE_KINDS else f"the free space at the {r.label}",
                               round_key(ans.point)))
        else:
            if final_orient:
                orient(ans.object_id)
            pos(ans.object_id)
    return out
