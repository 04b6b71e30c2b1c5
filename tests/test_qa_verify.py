"""Independent verification: generated QA pass; planted errors are each reported; YAML-only families."""

from __future__ import annotations

import copy
import json
from pathlib import Path

import numpy as np
import pytest

from refspatial_gen.cli import main
from refspatial_gen.core.model import Sample
from refspatial_gen.graph import build_graph
from refspatial_gen.qa import generate_qa, verify_sample
from refspatial_gen.qa.bench import default_config
from refspatial_gen.qa.verify import verify_samples
from refspatial_gen.sources.toy import toy_frame

REPO = Path(__file__).resolve().parents[1]


@pytest.fixture(scope="module")
def samples():
    cfg = default_config()
    out = []
    for i in range(8):
        f = toy_frame(np.random.default_rng(300 + i), 7, frame_id=f"toy:{i:06d}")
        g = build_graph(f)
        out.append(Sample(f"toy:{i:06d}", [f], [g], generate_qa([f], [g], np.random.default_rng(i), cfg)))
    return out


def _reasons(sample, qa_id):
    return [x["reason"] for x in verify_sample(sample) if x["qa_id"] == qa_id]


def _with(sample, qa):
    s = copy.copy(sample)
    s.qa = [qa]
    return s


def _find(samples, pred):
    for s in samples:
        for q in s.qa:
            if pred(q):
                return s, copy.deepcopy(q)
    pytest.fail("no QA pair of the wanted kind was generated")


def test_generated_qa_all_pass(samples):
    res = verify_samples(samples)
    assert res["qa_pairs"] >= 80
    assert res["failed"] == 0, res["failures"][:5]
    assert set(res) == {"qa_pairs", "passed", "failed", "failures"}


def test_moved_point_is_reported(samples):
    s, q = _find(samples, lambda q: q.answer_struct["kind"] == "points")
    f = s.frames[0]
    m = f.object(q.targets[0]).mask.decode()
    ys, xs = np.nonzero(~m)
    p = ((xs[0] + 0.5) / 320, (ys[0] + 0.5) / 240)
    q.answer_struct["points"] = [[round(p[0], 3), round(p[1], 3)]]
    q.answer = f"[({p[0]:.3f}, {p[1]:.3f})]"
    assert any("outside the visible mask" in r for r in _reasons(_with(s, q), q.qa_id))


def test_non_unique_phrase_is_reported(samples):
    def ambiguous(s, q):
        cats = [o.category for o in s.frames[0].objects]
        for st in q.program:
            for v in st["args"].values():
                if isinstance(v, dict) and "phrase" in v and cats.count(s.graphs[0].node(v["object"]).category) > 1:
                    return st, v
        return None

    for s in samples:
        for q0 in s.qa:
            hit = ambiguous(s, q0)
            if hit is None:
                continue
            q = copy.deepcopy(q0)
            st, v = ambiguous(s, q)
            bare = "the " + s.graphs[0].node(v["object"]).category
            q.question = q.question.replace(v["phrase"], bare)
            v["phrase"] = bare
            reasons = _reasons(_with(s, q), q.qa_id)
            assert any("not a unique reference" in r for r in reasons), reasons
            return
    pytest.fail("no QA pair names an object whose category is shared")


def test_degenerate_step_is_reported(samples):
    """Append a relation to a described target that every candidate already satisfies."""
    from refspatial_gen.graph.query import GraphIndex

    for s in samples:
        gi = GraphIndex(s.graphs[0])
        for q0 in s.qa:
            if q0.template != "locate/relation":
                continue
            q = copy.deepcopy(q0)
            filt, rel, loc = q.program
            target = loc["out"]["object"]
            anchor = rel["args"]["anchor"]["object"]
            for other in gi.referable():
                if other in (target, anchor):
                    continue
                for r2 in ("left", "right", "front", "behind"):
                    f = gi.fact(r2, target, other)
                    if f is None or f.holds is not True:
                        continue
                    extra = {
                        "op": "relate",
                        "as": "extra",
                        "weight": 2,
                        "out": [target],
                        "args": {
                            "in": {"step": rel["as"]},
                            "relation": r2,
                            "anchor": {"slot": "x", "object": other, "phrase": gi.phrase(other)},
                        },
                    }
                    loc["args"]["of"] = {"step": "extra"}
                    q.program = [filt, rel, extra, loc]
                    q.steps += 2
                    q.question += f" It is {r2} of {gi.phrase(other)}."
                    reasons = _reasons(_with(s, q), q.qa_id)
                    assert any("degenerate step 3" in r for r in reasons), reasons
                    return
    pytest.fail("no locate/relation pair to plant a redundant step in")


def test_wrong_distance_is_reported(samples):
    s, q = _find(samples, lambda q: q.answer_struct.get("quantity") == "distance")
    q.answer_struct["value"] = q.answer_struct["value"] + 0.2
    q.answer = f"{round(q.answer_struct['value'] * 100)} centimeters"
    reasons = _reasons(_with(s, q), q.qa_id)
    assert any("distance: answer" in r and "geometry gives" in r for r in reasons), reasons


def test_trace_tampering_is_reported(samples):
    s, q = _find(samples, lambda q: q.steps >= 2 and q.key_steps)
    q.trace = q.trace.replace(q.key_steps[0].phrase, "the mystery object", 1)
    assert any("differs from key step" in r for r in _reasons(_with(s, q), q.qa_id))


def test_wrong_choice_is_reported(samples):
    s, q = _find(
        samples, lambda q: q.answer_struct["kind"] == "choice" and sorted(q.answer_struct["options"]) == ["no", "yes"]
    )
    k = "AB".index(q.answer_struct["letter"])
    other = "AB"[1 - k]
    q.answer_struct["letter"] = other
    q.answer_struct["answer"] = q.answer_struct["options"][1 - k]
    q.answer = f"({other})"
    assert any("re-evaluates" in r for r in _reasons(_with(s, q), q.qa_id))


NEW_FAMILY = """\
# a new family, added as YAML only
templates:
  - name: lower_than
    slots:
      a: object
      b: anchor
    program:
      - {op: compare, relation: below_image, a: a, b: b}
    text:
      - "From the image's point of view, is {a} lower than {b}? {choices}"
  - name: left_of_anchor
    slots:
      cat: category
      b: anchor
    program:
      - {op: filter, category: cat}
      - {op: relate, relation: left, anchor: b}
      - {op: locate}
    text:
      - "Which {cat} is {to the left of|left of} {b}? Point to it."
"""


def test_new_template_family_is_yaml_only(tmp_path):
    from refspatial_gen.recipe import load_recipe

    (tmp_path / "mine").mkdir()
    (tmp_path / "mine" / "lower.yaml").write_text(NEW_FAMILY)
    r = tmp_path / "recipe.yaml"
    r.write_text(
        "name: mine\nsources:\n  - {kind: toy}\nqa:\n  max_per_sample: 6\n  families:\n"
        "    spatial_new: {weight: 1.0, templates: [mine/lower.yaml]}\n"
    )
    recipe = load_recipe(r)
    assert [f.name for f in recipe.qa.families] == ["spatial_new"]
    out = []
    for i in range(3):
        f = toy_frame(np.random.default_rng(400 + i), 7, frame_id=f"new:{i}")
        g = build_graph(f)
        s = Sample(f"new:{i}", [f], [g], generate_qa([f], [g], np.random.default_rng(i), recipe.qa))
        out.append(s)
    qas = [q for s in out for q in s.qa]
    assert qas and {q.family for q in qas} == {"spatial_new"}
    assert {q.template for q in qas} == {"spatial_new/lower_than", "spatial_new/left_of_anchor"}
    res = verify_samples(out)
    assert res["failed"] == 0 and res["passed"] == len(qas)


def test_verify_command_on_a_shard_dir(samples, tmp_path, capsys):
    from refspatial_gen.shards.index import write_index
    from refspatial_gen.shards.writer import ShardWriter

    w = ShardWriter(tmp_path / "shard-00000.mcap", image_format="png")
    for s in samples[:3]:
        w.write(s)
    write_index(tmp_path, [i.to_dict() for i in w.finish()], {"seed": 0})
    assert main(["verify", str(tmp_path), "--json"]) == 0
    res = json.loads(capsys.readouterr().out)
    assert res["qa_pairs"] == sum(len(s.qa) for s in samples[:3]) and res["failed"] == 0 and res["failures"] == []
    # a tampered copy fails, with the reason
    bad = copy.deepcopy(next(s for s in samples[3:] if any(q.answer_struct["kind"] == "number" for q in s.qa)))
    q = next(q for q in bad.qa if q.answer_struct["kind"] == "number")
    q.answer_struct["value"] += 0.5
    d2 = tmp_path / "bad"
    w = ShardWriter(d2 / "shard-00000.mcap", image_format="png")
    w.write(bad)
    write_index(d2, [i.to_dict() for i in w.finish()], {"seed": 0})
    assert main(["verify", str(d2), "--json"]) == 1
    res = json.loads(capsys.readouterr().out)
    assert res["failed"] == 1 and res["failures"][0]["qa_id"] == q.qa_id and res["failures"][0]["reason"]
