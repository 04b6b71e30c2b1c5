"""generate_qa on real toy frames: formats, checks, balance, determinism, multi-view, visual choice."""

from __future__ import annotations

import json
import re
from collections import Counter

import numpy as np
import pytest

from refspatial_gen.core.camera import Camera, look_at
from refspatial_gen.core.mask import denormalise_point
from refspatial_gen.core.serialize import dumps
from refspatial_gen.graph import build_graph
from refspatial_gen.graph.relations import SPEC_31
from refspatial_gen.qa import generate_qa
from refspatial_gen.qa.bench import default_config, qa_throughput
from refspatial_gen.qa.executor import Context, Search, degenerate_steps
from refspatial_gen.qa.generate import scene_index
from refspatial_gen.qa.index import Reject
from refspatial_gen.qa.templates import compile_templates
from refspatial_gen.sources.toy import TABLE, toy_frame

POINTS = re.compile(r"^\[\(\d\.\d{3}, \d\.\d{3}\)\]$")
CHOICE = re.compile(r"^\([A-H]\)( .+)?$")
TRACE = re.compile(
    r"^<think>(\[(Position|Orientation|Size)\] \[[^\]]+\]: (\([-0-9., ]+\)|\d+\.\d{3} m)\n?)+"
    r"</think><answer>.+</answer>$"
)


@pytest.fixture(scope="module")
def cfg():
    return default_config()


@pytest.fixture(scope="module")
def scenes():
    out = []
    for i in range(6):
        f = toy_frame(np.random.default_rng(200 + i), 7, frame_id=f"toy:{i:06d}")
        out.append((f, build_graph(f)))
    return out


@pytest.fixture(scope="module")
def generated(scenes, cfg):
    return [(f, g, generate_qa([f], [g], np.random.default_rng(i), cfg)) for i, (f, g) in enumerate(scenes)]


def test_every_qa_pair_is_well_formed(generated):
    fams = Counter()
    for f, _g, qas in generated:
        assert 5 <= len(qas) <= 15
        assert len({q.qa_id for q in qas}) == len(qas)
        assert len({q.question for q in qas}) == len(qas)
        for q in qas:
            fams[q.family] += 1
            assert 1 <= q.steps <= 5
            assert q.frame_ids == [f.frame_id] and tuple(q.image_size) == (320, 240)
            assert set(q.relations) <= set(SPEC_31) | {"next_to", "on"}
            assert {"unique_references", "nondegenerate", "outside_margin", "balanced"} <= set(q.checks)
            kind = q.answer_struct["kind"]
            if kind in ("points", "region"):
                assert POINTS.match(q.answer), q.answer
                assert "[(x1, y1)" in q.question or "[(x, y)]" in q.question
            elif kind == "choice":
                assert CHOICE.match(q.answer), q.answer
                assert "(A)" in q.question and "(B)" in q.question
            else:
                assert kind == "number" and re.search(r"(centimeters?|meters?|feet|foot|inch(es)?|degrees)$", q.answer)
            if q.steps >= 2:
                assert TRACE.match(q.trace), q.trace
                assert q.trace.endswith(f"<answer>{q.answer}</answer>")
            assert q.key_steps and all(k.type in ("Position", "Orientation", "Size") for k in q.key_steps)
            assert q.program and q.program[-1]["out"] is not None
            json.dumps(q.to_json())
    assert set(fams) >= {"locate", "identify", "placement", "choice", "quantitative", "visual_choice"}


def test_point_answers_lie_in_the_target_mask(generated):
    n = 0
    for f, _g, qas in generated:
        for q in qas:
            if q.answer_struct["kind"] != "points":
                continue
            ((x, y),) = q.answer_struct["points"]
            px, py = denormalise_point(x, y, 320, 240)
            assert f.object(q.targets[0]).mask.decode()[py, px]
            n += 1
    assert n >= 10


def test_same_seed_same_bytes(scenes, cfg):
    f, g = scenes[0]
    a = [q.to_json() for q in generate_qa([f], [g], np.random.default_rng(5), cfg)]
    b = [q.to_json() for q in generate_qa([f], [g], np.random.default_rng(5), cfg)]
    c = [q.to_json() for q in generate_qa([f], [g], np.random.default_rng(6), cfg)]
    assert dumps(a) == dumps(b)
    assert dumps(a) != dumps(c)


def test_yes_no_and_letters_are_balanced(scenes, cfg):
    yes = Counter()
    letters = Counter()
    for k in range(6):
        for i, (f, g) in enumerate(scenes):
            for q in generate_qa([f], [g], np.random.default_rng(100 * k + i), cfg):
                s = q.answer_struct
                if s["kind"] == "choice":
                    letters[s["letter"] if len(s["options"]) == 2 else "multi"] += 1
                    if sorted(s["options"]) == ["no", "yes"]:
                        yes[s["answer"]] += 1
    assert yes["yes"] + yes["no"] >= 20
    assert 0.4 <= yes["yes"] / (yes["yes"] + yes["no"]) <= 0.6, yes
    assert 0.35 <= letters["A"] / (letters["A"] + letters["B"]) <= 0.65, letters


def _one_template(text: str):
    import yaml

    errors = []
    ts = compile_templates(yaml.safe_load(text), "t.yaml", {}, errors)
    assert not errors, errors
    ts[0].family = "test"
    return ts[0]


def test_degenerate_step_is_detected(scenes):
    """A relate step that does not narrow the described set makes the question degenerate."""
    t = _one_template("""
templates:
  - name: t
    slots:
      {cat: category, r1: {type: relation, choices: [left]}, a1: anchor, r2: {type: relation, choices: [right]},
       a2: anchor}
    program:
      - {op: filter, category: cat}
      - {op: relate, relation: r1, anchor: a1}
      - {op: relate, relation: r2, anchor: a2}
      - {op: locate}
    text: ["the {cat} {r1} {a1} {r2} {a2}"]
""")
    f, g = scenes[0]
    ctx = Context(scene_index(f, g), np.random.default_rng(0), prune=True)
    idx = ctx.idx
    # build an instance by hand: target x, a1 right of x, a2 left of x, with the second relate redundant
    found = None
    for cat in idx.categories:
        for x in idx.by_category[cat]:
            for a1 in idx.referable:
                for a2 in idx.referable:
                    if len({x, a1, a2}) < 3:
                        continue
                    try:
                        s1 = idx.narrow("left", a1, idx.by_category[cat])
                        s2 = idx.narrow("right", a2, s1)
                    except Reject:
                        continue
                    if s1 == s2 == frozenset({x}):
                        found = (cat, x, a1, a2, s1)
    assert found, "no scene configuration with a redundant relation"
    cat, x, a1, a2, s1 = found
    env = {
        "cat": cat,
        "r1": "left",
        "a1": a1,
        "r2": "right",
        "a2": a2,
        "step1": idx.by_category[cat],
        "step2": s1,
        "step3": s1,
        "step4": None,
    }
    from refspatial_gen.qa.executor import PointValue

    env["step4"] = PointValue(idx.point(x), x)
    assert 2 in degenerate_steps(t, env, ctx)
    # and the search never yields such an instance
    for inst in Search(t, ctx, 5000).instances():
        assert not (inst["cat"] == cat and inst["a1"] == a1 and inst["a2"] == a2)


def test_undecided_relation_is_never_asked(scenes):
    """Planting an undecided stored fact: asking it is rejected with reason 'margin', both one pair at a time
    (holds, through the relation table) and set-at-once (the relate step's entry lists it as undecided)."""
    from refspatial_gen.core.model import RelationFact, SceneGraph
    from refspatial_gen.qa.index import SceneIndex

    f, g = scenes[1]
    g2 = SceneGraph.from_json(g.to_json())
    a, b = sorted(n.object_id for n in g2.nodes if n.phrases and n.point is not None)[:2]
    g2.facts = [x for x in g2.facts if not (x.relation == "left" and set(x.args) == {a, b})]
    g2.facts.append(RelationFact("left", (a, b), None, 0.001, 0.01))
    idx = SceneIndex(f, g2)
    for args in ((a, b), (b, a)):
        with pytest.raises(Reject) as e:
            idx.holds("left", args)
        assert e.value.reason == "margin"
    t, u, m = idx.rel_entry("left", b)
    assert a in u and a not in t
    with pytest.raises(Reject) as e:
        idx.narrow("left", b, frozenset({a}))
    assert e.value.reason == "margin"


def test_multiview_camera_turn(cfg):
    rng = np.random.default_rng(3)
    f1 = toy_frame(rng, 5, frame_id="mv:0")
    boxes = [(o.category, o.attributes["color"], o.box) for o in f1.objects]
    w, h = 320, 240
    fl = w / (2 * np.tan(np.deg2rad(30)))
    top = TABLE.top_z
    eye = np.array([0.0, -0.9, top + 0.7])
    target_left = np.array([-0.25, 0.0, top])  # the second camera looks further left: it turned left
    c2 = Camera(w, h, fl, fl, w / 2, h / 2, look_at(eye, target_left))
    c1 = Camera(w, h, fl, fl, w / 2, h / 2, look_at(eye, np.array([0.15, 0.0, top])))
    fa = toy_frame(rng, boxes=boxes, camera=c1, frame_id="mv:0")
    fb = toy_frame(rng, boxes=boxes, camera=c2, frame_id="mv:1")
    fa.scene_id = fb.scene_id = "mv"
    ga, gb = build_graph(fa), build_graph(fb)
    seen = []
    for k in range(12):
        for q in generate_qa([fa, fb], [ga, gb], np.random.default_rng(k), cfg):
            if q.family == "multiview":
                seen.append(q)
                word = q.answer_struct["answer"]
                if "left or right" in q.question:
                    assert word == ("left" if q.frame_ids == ["mv:0", "mv:1"] else "right")
                    assert q.relations == ["rotation_horizontal"]
    assert seen and all(len(q.frame_ids) == 2 for q in seen)


def test_visual_choice_marks_travel_in_answer_struct(generated):
    vc = [q for _, _, qas in generated for q in qas if q.family == "visual_choice"]
    assert vc
    for q in vc:
        marks = q.answer_struct["marks"]
        assert [m["label"] for m in marks] == ["A", "B", "C"][: len(marks)]
        assert all(m["style"] in ("box", "point") and m["view"] == 0 for m in marks)
        k = "ABC".index(q.answer_struct["letter"])
        assert q.targets == [marks[k]["object_id"]]


def test_bench_reports_throughput(scenes, cfg):
    r = qa_throughput(scenes[:3], seconds=0.5, config=cfg)
    assert r["qa_pairs"] > 0 and r["qa_per_second_per_core"] > 0 and r["qa_per_sample"] >= 5


def test_index_facts_equal_the_graph_query_index(scenes):
    """The QA index answers exactly what graph.query.GraphIndex answers (bulk size comparisons included)."""
    from itertools import permutations

    from refspatial_gen.graph.query import GraphIndex
    from refspatial_gen.qa.index import SceneIndex

    for f, g in scenes[:3]:
        idx, gi = SceneIndex(f, g), GraphIndex(g, f)
        for rel in (
            "tall",
            "short",
            "big",
            "small",
            "wide",
            "thin",
            "left",
            "right",
            "front",
            "behind",
            "above_image",
            "below_image",
            "above_world",
            "below_world",
            "touching",
            "facing",
        ):
            for a, b in permutations(idx.ids, 2):
                mine, ref = idx.fact(rel, (a, b)), gi.fact(rel, a, b)
                assert (mine is None) == (ref is None)
                if ref is not None:
                    assert mine.holds == ref.holds and abs(mine.value - ref.value) < 1e-12, (rel, a, b)


def test_key_steps_always_name_their_object(scenes, cfg):
    """Objects without a unique phrase (half the nodes here) may be described in a question, but a key step can
    only name a graph phrase, a drawn mark, the free space, or (final position only) the answer target: the
    generator rejects anything else, as `verify` would."""
    from refspatial_gen.core.model import KeyStep, SceneGraph
    from refspatial_gen.qa.keysteps import check_key_phrases as _check_key_phrases

    emitted = 0
    for k, (f, g) in enumerate(scenes):
        g2 = SceneGraph.from_json(g.to_json())
        for n in g2.nodes[::2]:
            n.phrases = []
        idx = scene_index(f, g2)
        for seed in range(4):
            for qa in generate_qa([f], [g2], np.random.default_rng(1000 * k + seed), cfg):
                emitted += 1
                for ks in qa.key_steps[:-1]:
                    assert ks.phrase in idx.phrase_set or ks.phrase.startswith(("the object marked", "the free space"))
    assert emitted > 100
    idx = scene_index(*scenes[0])
    named = next(iter(idx.phrase_set))
    ok = [KeyStep("Position", named, [0.5, 0.5]), KeyStep("Position", "the target cup", [0.5, 0.5])]
    _check_key_phrases(ok, {}, [1], idx)  # an unnamed final answer target is fine
    with pytest.raises(Reject):
        _check_key_phrases(ok[::-1], {}, [1], idx)  # an unnamed object on the way is not
    with pytest.raises(Reject):
        _check_key_phrases([KeyStep("Size", "the target cup", [0.1, 0.1, 0.1])], {}, [1], idx)


def test_marks_name_the_asked_view_in_a_multi_view_sample(cfg):
    """Visual-choice marks carry the position of the asked frame among the sample's frames (the exporter and
    the preview draw them on that image); verify rejects marks pointing at another view."""
    import dataclasses

    from refspatial_gen.core.model import Sample
    from refspatial_gen.qa.verify import verify_sample

    rng = np.random.default_rng(5)
    fa = toy_frame(rng, 7, frame_id="mk:0")
    boxes = [(o.category, o.attributes["color"], o.box) for o in fa.objects]
    fb = toy_frame(rng, boxes=boxes, frame_id="mk:1")
    fa.scene_id = fb.scene_id = "mk"
    ga, gb = build_graph(fa), build_graph(fb)
    only = dataclasses.replace(cfg, families=[f for f in cfg.families if f.name == "visual_choice"])
    views = Counter()
    planted_checks = 0
    for k in range(20):
        qa = generate_qa([fa, fb], [ga, gb], np.random.default_rng(k), only)
        sample = Sample("s", [fa, fb], [ga, gb], qa, "s", {})
        assert verify_sample(sample) == []
        for q in qa:
            marks = q.answer_struct.get("marks") or []
            for m in marks:
                assert [fa, fb][m["view"]].frame_id == q.frame_ids[0]
                views[m["view"]] += 1
        planted = [q for q in qa if q.answer_struct.get("marks") and q.frame_ids[0] == "mk:1"]
        if planted:
            q = planted[0]
            q.answer_struct["marks"][0]["view"] = 0
            reasons = [r["reason"] for r in verify_sample(Sample("s", [fa, fb], [ga, gb], [q], "s", {}))]
            assert any("not on the asked frame" in r for r in reasons), reasons
            planted_checks += 1
    assert views[0] and views[1] and planted_checks  # questions were asked on both views, a wrong view caught
