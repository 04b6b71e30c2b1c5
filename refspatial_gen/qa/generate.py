"""generate_qa: pick families and templates, search bindings, run every check, render QA pairs.

Why the checks live here and not in templates: a recipe author cannot forget them. Every QA pair has
unique references (named objects by their graph phrase, described targets resolve to exactly one
object), no degenerate step (dropping any counted step changes the answer), no relation inside its
margin (an undecided fact rejects the binding), and balanced answers (yes/no drawn to even out,
letters shuffled, answer points spread over image quadrants by rejection).
"""

from __future__ import annotations

from collections import OrderedDict
from typing import Any

import numpy as np

from refspatial_gen.core.model import Frame, QAPair, SceneGraph
from refspatial_gen.qa.config import QAConfig
from refspatial_gen.qa.executor import Search, degenerate_steps, slot_candidates
from refspatial_gen.qa.faint import withhold
from refspatial_gen.qa.index import Reject, SceneIndex
from refspatial_gen.qa.nesting import nested_phrase
from refspatial_gen.qa.ops.base import BOOL, OBJECT
from refspatial_gen.qa.program import Template
from refspatial_gen.qa.recognisable import withhold_cut
from refspatial_gen.qa.record import build_pair
from refspatial_gen.qa.sample_rng import SampleRng
from refspatial_gen.qa.values import Context, PointValue

_MISS = object()


class _IndexCache:
    """The few most recent graph -> SceneIndex entries. Bounded on purpose: a WeakKeyDictionary never freed
    anything here, because each index refers to its own graph (memory grew ~6 MB per scene in a worker)."""

    def __init__(self, size: int = 8) -> None:
        self._d: OrderedDict[int, tuple[SceneGraph, SceneIndex]] = OrderedDict()
        self.size = size

    def get(self, graph: SceneGraph) -> SceneIndex | None:
        e = self._d.get(id(graph))
        return e[1] if e is not None and e[0] is graph else None

    def __setitem__(self, graph: SceneGraph, idx: SceneIndex) -> None:
        self._d[id(graph)] = (graph, idx)
        self._d.move_to_end(id(graph))
        while len(self._d) > self.size:
            self._d.popitem(last=False)

    def pop(self, graph: SceneGraph, default: SceneIndex | None = None) -> SceneIndex | None:
        e = self._d.pop(id(graph), None)
        return default if e is None or e[0] is not graph else e[1]


_INDEX_CACHE = _IndexCache()


def scene_index(frame: Frame, graph: SceneGraph) -> SceneIndex:
    """The cached lookup index of a (frame, graph) pair (built once per graph object), for callers that query
    the same graph many times (tests, the warm-index bench); generate_qa builds its own unless given one."""
    idx = _INDEX_CACHE.get(graph)
    if idx is None or idx.frame is not frame:
        idx = SceneIndex(frame, graph)
        _INDEX_CACHE[graph] = idx
    return idx


class Balancer:
    """Per-call counters that keep answers even: yes/no, answer letters and answer-point quadrants."""

    def __init__(self, slack: int) -> None:
        self.slack = slack
        self.yes_no = [0, 0]
        self.quadrants = [0, 0, 0, 0]
        self._allowed: dict[tuple[Any, ...], frozenset[Any] | None] = {}

    def want_bool(self, rng: SampleRng) -> bool:
        if self.yes_no[0] != self.yes_no[1]:
            return self.yes_no[0] < self.yes_no[1]  # index 0 counts "yes"
        return bool(rng.integers(2))

    @staticmethod
    def quadrant(p: tuple[float, float]) -> int:
        return int(p[0] >= 0.5) + 2 * int(p[1] >= 0.5)

    def point_ok(self, p: tuple[float, float]) -> bool:
        return self.quadrants[self.quadrant(p)] <= min(self.quadrants) + self.slack

    def allowed_answers(self, idx: SceneIndex) -> frozenset[Any] | None:
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
        return hit  # type: ignore[return-value]

    def add(self, answer: Any) -> None:
        if isinstance(answer, bool):
            self.yes_no[0 if answer else 1] += 1
        elif isinstance(answer, PointValue):
            self.quadrants[self.quadrant(answer.point)] += 1


def generate_qa(
    frames: list[Frame],
    graphs: list[SceneGraph],
    rng: np.random.Generator,
    config: QAConfig,
    indexes: list[SceneIndex] | None = None,
    truth: dict[str, int] | None = None,
) -> list[QAPair]:
    """Up to `config.max_per_sample` checked QA pairs for one sample (one frame or a multi-view group).
    `truth`: a dict the truth checks (qa/faint.py) add their withheld pairs to, by reason.

    The lookup indexes are built for this call and freed with it (a run uses each graph in one sample only;
    keeping them would only give the garbage collector more to scan). Callers that ask several times of the
    same graphs (tests, the warm-index bench) pass `indexes` (scene_index) to reuse them.
    """
    if len(frames) != len(graphs):
        raise ValueError(f"{len(frames)} frames but {len(graphs)} graphs")
    if indexes is not None and (
        len(indexes) != len(frames)
        or any(i.frame is not f or i.graph is not g for i, f, g in zip(indexes, frames, graphs))
    ):
        raise ValueError("indexes must be the SceneIndex of each (frame, graph), in order")
    idxs = indexes or [SceneIndex(f, g) for f, g in zip(frames, graphs)]
    return _generate(frames, idxs, rng, config, {} if truth is None else truth)


def _generate(
    frames: list[Frame],
    idxs: list[SceneIndex],
    sample_rng: np.random.Generator,
    config: QAConfig,
    truth: dict[str, int],
) -> list[QAPair]:
    rng = SampleRng(sample_rng)  # template QA draws from a fast generator seeded by the sample's
    pairs = [
        (i, j)
        for i in range(len(frames))
        for j in range(len(frames))
        if i != j and frames[i].scene_id and frames[i].scene_id == frames[j].scene_id
    ]
    bal = Balancer(config.point_slack)
    out: list[QAPair] = []
    seen: set[Any] = set()
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
        qid = f"{frames[i].frame_id}:{len(out):02d}"  # the asked view (the first of a view pair)
        qa = _instantiate(t, ctx, rng, config, bal, seen, fids, qid, view=i, truth=truth)
        if qa is None and t.answer_type == BOOL:  # the other answer may exist (the balancer catches up)
            qa = _instantiate(t, ctx, rng, config, bal, seen, fids, qid, flip=True, view=i, truth=truth)
        if qa is None:
            exhausted.add(id(t))  # no binding passed in this sample: do not spend more attempts on it
            continue
        out.append(qa)
        per_family[fam.name] = per_family.get(fam.name, 0) + 1
        if _is_multiview(t):
            mv_count += 1
    if config.point_depth:  # built-in camera-frame point/depth questions (work on frames without objects)
        from refspatial_gen.qa.pointdepth import point_depth_qa

        n_pd = min(config.point_depth, config.max_per_sample - len(out))
        out += point_depth_qa(frames, sample_rng, n_pd, len(out), truth=truth)
    return out


_FAMILY_PLANS: dict[tuple[int, int], tuple[Any, ...]] = {}


def _family_choices(fam: Any, config: QAConfig, exhausted: set[int], multiview: bool) -> tuple[list[Any], list[Any]]:
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
        plan = (
            fam,
            config,
            temps,
            weights,
            multi,
            frozenset(id(t) for t in temps),
            ([temps[k] for k in single], [weights[k] for k in single]) if any(multi) else (temps, weights),
        )
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


def _is_multiview(t: Template) -> bool:
    return t.program.needs.multiview


def _instantiate(
    t: Template,
    ctx: Context,
    rng: SampleRng,
    config: QAConfig,
    bal: Balancer,
    seen: set[Any],
    frame_ids: list[str],
    qa_id: str,
    flip: bool = False,
    view: int = 0,
    truth: dict[str, int] | None = None,
) -> QAPair | None:
    """One checked QA pair of template t on ctx's frame (`view`: that frame's position in the sample), or None."""
    needs = t.program.needs
    if needs.spot and not ctx.idx.has_true_spot:
        return None  # an `at` step keeps objects at a corner/edge; with none anywhere every binding is empty
    if needs.between and ctx.idx.largest_between_row < needs.between:
        return None  # a `between` step must keep that many objects; no anchor pair has that many between it
    if needs.between_region and not ctx.idx.has_between_region:
        return None  # free space between two anchors, and the graph has no such region
    want = bal.want_bool(rng) if t.answer_type == BOOL else None
    if flip and want is not None:
        want = not want
    last = t.steps[-1].name
    slots = needs.slot_names
    is_obj = t.answer_type == OBJECT
    idx = ctx.idx

    def accept(env: dict[str, Any]) -> QAPair | None:
        ans = env[last]
        if want is not None and ans is not want:
            return None
        if is_obj:
            if ans not in idx.answer_points:
                return None  # an object without an answer point (hidden, below the visibility floor)
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
        if (why := nested_phrase(t, env, ctx)) is not None:
            if truth is not None:
                truth[why] = truth.get(why, 0) + 1
            return None
        try:
            extra = _bind_text_only(t, env, ctx)
            qa = build_pair(t, {**env, **extra}, ans, ctx, rng, frame_ids, qa_id, view)
        except Reject:
            return None
        why = withhold_cut(t, env, ctx, qa) or withhold(t, env, ctx, qa)  # recognisable.py, faint.py
        if why is not None:
            if truth is not None:
                truth[why] = truth.get(why, 0) + 1
            return None
        seen.add(key)
        bal.add(env[last] if t.answer_type == BOOL else ans)
        return qa

    answers = bal.allowed_answers(idx) if any(t.program.answer_chain) else None
    return Search(t, ctx, config.budget, answers).first(accept)


def _hashable(v: Any) -> Any:
    if isinstance(v, (int, str, float, bool, tuple)):
        return v
    return (type(v).__name__, id(v))


def _bind_text_only(t: Template, env: dict[str, Any], ctx: Context) -> dict[str, Any]:
    out = {}
    for name in t.unbound:
        c = slot_candidates(t, name, env, ctx)
        if not c:
            raise Reject("no_candidate")
        out[name] = c[int(ctx.rng.integers(len(c)))]
    return out
