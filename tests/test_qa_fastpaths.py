"""The QA engine's fast paths (set-at-once relation and `between` entries, the close/far winner from
distances, compiled steps, skipped replays and searches) must give exactly what the member-wise path gives."""

from __future__ import annotations

from itertools import permutations

import numpy as np
import pytest

from refspatial_gen.core.model import RelationFact, SceneGraph
from refspatial_gen.graph.query import GraphIndex
from refspatial_gen.qa.index import Reject, SceneIndex
from tests.helpers.scenes import toy_scenes


@pytest.fixture(scope="module")
def scenes():
    out = toy_scenes(range(100, 104), 7)
    # toy scenes have no containment or contact: a copy of one graph with stored inside / touching instances
    # (true, undecided, and touching stored in the reverse direction) exercises those tables too
    f, g = out[0]
    g2 = SceneGraph.from_json(g.to_json())
    a, b, c, d, e = sorted(n.object_id for n in g2.nodes)[:5]
    g2.facts += [
        RelationFact("inside", (a, b), True, 0.9, 0.1),
        RelationFact("inside", (c, d), None, 0.3, 0.1),
        RelationFact("touching", (b, a), True, 0.0, 0.01),
        RelationFact("touching", (d, e), None, 0.01, 0.01),
    ]
    out.append((f, g2))
    return out


def test_scene_index_between_set_matches_memberwise(scenes):
    for f, g in scenes:
        idx, ref = SceneIndex(f, g), GraphIndex(g, f)
        for b, c in permutations(idx.ids, 2):
            s = idx.all
            members = [x for x in sorted(s) if x not in (b, c)]
            facts = [ref.fact("between", x, b, c) for x in members]
            if any(fa is None or fa.holds is None for fa in facts):
                with pytest.raises(Reject):
                    idx.between(b, c, s)
            else:
                assert idx.between(b, c, s) == frozenset(x for x, fa in zip(members, facts) if fa.holds)


RELATE_RELATIONS = (
    "left",
    "right",
    "front",
    "behind",
    "above_image",
    "below_image",
    "above_world",
    "below_world",
    "tall",
    "short",
    "big",
    "small",
    "wide",
    "thin",
    "far_from",
    "facing",
    "facing_away",
    "outside",
    "inside",
    "touching",
    "next_to",
)


def test_relation_tables_match_memberwise_facts(scenes):
    """rel_entry fills whole tables from stored facts; each entry equals the member-wise GraphIndex answer."""
    kinds = {True: 0, None: 0, False: 0}
    seen: set[str] = set()
    for f, g in scenes:
        idx, ref = SceneIndex(f, g), GraphIndex(g, f)
        for rel in RELATE_RELATIONS:
            for anchor in idx.ids:
                t, u, m = idx.rel_entry(rel, anchor)
                for x in idx.ids:
                    if x == anchor:
                        assert x not in t | u | m
                        continue
                    want = ref.fact(rel, x, anchor)
                    got = "missing" if x in m else (True if x in t else (None if x in u else False))
                    assert got == ("missing" if want is None else want.holds), (rel, x, anchor)
                    if want is not None:
                        kinds[want.holds] += 1
                        if want.holds is not False:
                            seen.add(rel)
    assert all(kinds.values())  # true, false and undecided instances were all compared
    assert seen >= {"inside", "outside", "touching"}  # the planted containment/contact instances were reached


def test_compiled_steps_agree_with_run_step(scenes):
    """The search's compiled steps return what the reference interpreter returns (or rejects with)."""
    from itertools import product

    from refspatial_gen.qa.bench import default_config
    from refspatial_gen.qa.executor import Context, run_step, slot_candidates

    cfg = default_config()
    checked = 0
    for f, g in scenes[:2]:
        idx = SceneIndex(f, g)
        for fam in cfg.families:
            for t in fam.templates:
                fns = t.program.fns
                for st, fn in zip(t.steps, fns):
                    if st.op not in ("relate", "between") or st.impl.compile(st) is None:
                        continue
                    names = [n for n in t.slots if t.slots[n].type in ("relation", "object", "anchor")]
                    used = {r.value for r in st.args.values() if r.kind == "slot"} | {
                        x.value for r in st.args.values() if r.kind == "list" for x in r.value
                    }
                    cands = [
                        slot_candidates(t, n, {}, Context(idx, np.random.default_rng(0)))[:6]
                        for n in names
                        if n in used
                    ]
                    for prev in (None, idx.all, frozenset(list(idx.ids)[:4])):
                        for combo in product(*cands):
                            env = dict(zip([n for n in names if n in used], combo))
                            for prune in (True, False):
                                ctx = Context(idx, np.random.default_rng(0), prune=prune)
                                got = fn(env, prev, ctx)
                                try:
                                    want = run_step(st, env, prev, ctx)
                                except Reject as r:
                                    want = r
                                if isinstance(want, Reject):
                                    assert isinstance(got, Reject) and got.reason == want.reason, (t.name, env)
                                else:
                                    assert got == want, (t.name, env)
                                checked += 1
    assert checked > 1000


def test_close_far_winner_matches_pairwise_rule(scenes, monkeypatch):
    """Superlatives on close/far decide from the distances to the anchor; the pairwise elimination (facts one
    pair at a time) gives the same winner, or rejects too, for every anchor and candidate set tried."""
    from itertools import combinations

    from refspatial_gen.qa.ops.common import winner as _winner

    outcomes = {"winner": 0, "reject": 0}
    for f, g in scenes:
        idx = SceneIndex(f, g)
        for anchor in idx.ids:
            others = [x for x in idx.ids if x != anchor]
            for k in (1, 2, 3, len(others)):
                for cands in combinations(others, k):
                    for rel in ("close", "far"):
                        try:
                            fast = _winner(list(cands), rel, anchor, idx)
                        except Reject:
                            fast = "reject"
                        with monkeypatch.context() as mp:
                            mp.setattr(idx, "distances_to", lambda *a: None)  # force the pairwise path
                            try:
                                slow = _winner(list(cands), rel, anchor, idx)
                            except Reject:
                                slow = "reject"
                        assert fast == slow, (rel, anchor, cands)
                        outcomes["reject" if fast == "reject" else "winner"] += 1
    assert outcomes["winner"] > 100 and outcomes["reject"] > 10


def test_point_in_mask_matches_decoded_mask(scenes):
    """The RLE point test (bisect over run ends) agrees with the decoded mask on a grid of points."""
    from refspatial_gen.core.mask import normalise_point

    f, g = scenes[0]
    idx = SceneIndex(f, g)
    inside = 0
    for o in f.objects:
        m = o.mask.decode()
        for y in range(0, m.shape[0], 7):
            for x in range(0, m.shape[1], 7):
                p = normalise_point(x, y, idx.W, idx.H)
                assert idx.point_in_mask(o.id, p) == bool(m[y, x]), (o.id, x, y)
                inside += bool(m[y, x])
    assert inside > 0


def _degenerate_by_full_replay(t, env, ctx) -> list[int]:
    """degenerate_steps without its shortcuts: every droppable step is replayed, the whole program each time."""
    from refspatial_gen.qa.executor import answer_key, replay

    full, bad = answer_key(env[t.steps[-1].name]), []
    for st in t.steps:
        if st.impl.droppable:
            try:
                if replay(t, env, ctx, drop=st.index, reuse_prefix=False) == full:
                    bad.append(st.index)
            except Reject:
                pass
    return bad


def test_replay_with_compiled_steps_matches_interpreter(scenes, monkeypatch):
    """The degeneracy check replays programs with the compiled steps; the interpreter gives the same verdicts."""
    import dataclasses

    from refspatial_gen.qa.bench import default_config
    from refspatial_gen.qa.executor import Context, Search, degenerate_steps
    from refspatial_gen.qa.ops.common import generic

    cfg = default_config()
    checked = bad = 0
    for f, g in scenes[:3]:
        idx = SceneIndex(f, g)
        for fam in cfg.families:
            for t in fam.templates:
                if any(st.op == "camera_turn" for st in t.steps):
                    continue
                ctx = Context(idx, np.random.default_rng(1))
                for env in list(Search(t, ctx, 300).instances())[:15]:
                    fast = degenerate_steps(t, env, ctx)
                    interpreted = dataclasses.replace(
                        t, program=dataclasses.replace(t.program, fns=tuple(generic(st) for st in t.steps))
                    )
                    slow = degenerate_steps(interpreted, env, ctx)
                    assert fast == slow, (t.name, env)
                    assert fast == _degenerate_by_full_replay(t, env, ctx), (t.name, env)  # the skipped replays
                    checked += 1
                    bad += bool(fast)
    assert checked > 200 and bad > 0  # degenerate instances were among those compared


def test_decision_from_tables_matches_fact_path(scenes):
    """holds()/decision() answer binary relations from the relation tables; fact() (the stored facts through the
    graph's rules) must agree on every ordered pair, undecided and missing instances included."""
    from refspatial_gen.qa.index import NO_FACT

    seen = {True: 0, False: 0, None: 0, "missing": 0}
    for f, g in scenes:
        idx, ref = SceneIndex(f, g), SceneIndex(f, g)  # ref: a fresh index asked through fact() only
        for rel in RELATE_RELATIONS + ("distance", "angle", "on"):
            for a, b in permutations(idx.ids + (10_000,), 2):
                want = ref.fact(rel, (a, b))
                got = idx.decision(rel, (a, b))
                assert got is (NO_FACT if want is None else want.holds), (rel, a, b)
                seen["missing" if want is None else want.holds] += 1
    assert all(seen.values())


def test_compiled_steps_agree_on_search_instances(scenes):
    """Every compiled step (relate, between, filter, locate, compare) returns what run_step returns or rejects
    with, on the bindings the search really reaches, fed the previous step's value and other inputs."""
    from refspatial_gen.qa.bench import default_config
    from refspatial_gen.qa.executor import Context, Search, run_step

    cfg = default_config()
    checked: dict[str, int] = {}
    for f, g in scenes[:3]:
        idx = SceneIndex(f, g)
        singles = [frozenset({x}) for x in idx.ids[:3]]
        for fam in cfg.families:
            for t in fam.templates:
                if any(st.op == "camera_turn" for st in t.steps):
                    continue
                fns = t.program.fns
                for env in list(Search(t, Context(idx, np.random.default_rng(3)), 400).instances())[:10]:
                    for k, (st, fn) in enumerate(zip(t.steps, fns)):
                        if st.impl.compile(st) is None:
                            continue
                        own = env[t.steps[k - 1].name] if k else None
                        for prev in (own, None, idx.all, *singles, frozenset()):
                            for prune in (True, False):
                                ctx = Context(idx, np.random.default_rng(0), prune=prune)
                                try:
                                    got = fn(env, prev, ctx)
                                except Exception as e:  # a nonsense input (locate of nothing) fails alike
                                    got = e
                                try:
                                    want = run_step(st, env, prev, ctx)
                                except Reject as r:
                                    want = r
                                except Exception as e:
                                    assert type(got) is type(e), (t.name, st.op, prev)
                                    continue
                                if isinstance(want, Reject):
                                    assert isinstance(got, Reject) and got.reason == want.reason, (t.name, st.op)
                                else:
                                    assert got == want and type(got) is type(want), (t.name, st.op)
                                checked[st.op] = checked.get(st.op, 0) + 1
    assert {"relate", "between", "filter", "locate", "compare"} <= set(checked), checked
    assert min(checked.values()) > 50, checked


def test_has_true_spot_matches_every_spot_decision(scenes):
    """generate skips templates with an `at` step when no object is at any corner/edge; the shortcut must say
    yes exactly when some (object, spot) decision is true."""
    from refspatial_gen.core.model import RelationFact

    f, g = scenes[0]
    g2 = SceneGraph.from_json(g.to_json())
    g2.facts = [x for x in g2.facts if x.relation not in ("corner", "edge")]
    idx0 = SceneIndex(f, g2)
    spot = idx0.spots[0] if idx0.spots else None
    assert spot is not None, "the toy scene has labelled surface spots"
    a = sorted(n.object_id for n in g2.nodes if n.attributes.get("surface") == spot[1])[0]
    g3 = SceneGraph.from_json(g2.to_json())
    g3.facts.append(RelationFact(spot[0], (a, spot[1], spot[2]), True, 0.01, 0.02))
    outcomes = set()
    for ff, gg in [*scenes, (f, g2), (f, g3)]:
        idx = SceneIndex(ff, gg)
        any_true = any(idx.decision(k, (x, sid, lab)) is True for k, sid, lab in idx.spots for x in idx.ids)
        assert idx.has_true_spot == any_true
        outcomes.add(any_true)
    assert outcomes == {True, False}


def test_between_shortcut_only_skips_searches_that_cannot_succeed(scenes):
    """generate skips a template whose `between` step must keep more objects than any anchor pair has between
    it: largest_between_row is the largest true row, and with it below the bound the search finds nothing."""
    from refspatial_gen.qa.bench import default_config
    from refspatial_gen.qa.executor import Context, Search

    cfg = default_config()
    templates = [t for fam in cfg.families for t in fam.templates if t.program.needs.between]
    skipped = searched = 0
    small = toy_scenes((104, 105, 106), 5)  # five-object scenes: some have at most one object between any two
    for f, g in [*scenes, *small]:
        idx = SceneIndex(f, g)
        rows = [idx.between_entry(b, c)[0] for b, c in permutations(idx.ids, 2)]
        assert idx.largest_between_row == max(len(r) for r in rows)
        for t in templates:
            if idx.largest_between_row < t.program.needs.between:
                assert not list(Search(t, Context(idx, np.random.default_rng(0)), 10**6).instances()), t.name
                skipped += 1
            else:
                searched += 1
    assert skipped and searched
