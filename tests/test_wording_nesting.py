"""Referring expressions nest at most one level (audit round 2, sim:000020/v0:07: "the basket that is bigger
than the shortest basket that is closest to the basket closest to the orange"): an object named inside the
described object's relative clauses never has an anchored phrase, and no template chains a second clause
after an anchor, where English attaches it to the anchor."""

from __future__ import annotations

import re
from pathlib import Path

import numpy as np
import pytest
import yaml

from refspatial_gen.graph import build_graph
from refspatial_gen.qa import generate_qa
from refspatial_gen.qa.bench import default_config
from refspatial_gen.sources.toy import toy_frame

ANCHORED = re.compile(r"\b(closest to|farthest from|on) the\b")  # phrase forms of graph/phrases.py
TEMPLATES = Path(__file__).resolve().parent.parent / "recipes" / "templates"


def _nested(qa) -> list[str]:
    """Anchor phrases of set-narrowing steps (their record reads `in`) and of `choose` that name their object
    through another."""
    out = []
    for st in qa.program:
        args = st.get("args") or {}
        if "in" not in args and st.get("op") != "choose":
            continue
        anchors = args.get("anchors") or [args.get("anchor")]
        for a in anchors:
            if isinstance(a, dict) and ANCHORED.search(a.get("phrase", "")):
                out.append(a["phrase"])
    return out


@pytest.fixture(scope="module")
def generated():
    cfg = default_config()
    truth: dict[str, int] = {}
    out = []
    for i in range(6):
        f = toy_frame(np.random.default_rng(300 + i), 8, frame_id=f"toy:{i:06d}")
        g = build_graph(f)
        for n in g.nodes:  # toy scenes seldom need an anchored phrase: name half of the objects through another
            if n.phrases and n.object_id % 2:
                n.phrases.insert(0, f"the {n.category} {n.object_id} closest to the table")
        out += generate_qa([f], [g], np.random.default_rng(i), cfg, truth=truth)
    return out, truth


def test_no_anchored_phrase_inside_a_relative_clause(generated):
    pairs, truth = generated
    assert pairs
    bad = [(q.question, _nested(q)) for q in pairs if _nested(q)]
    assert not bad, bad[:3]
    assert truth.get("phrase_nested", 0) > 0  # the rule had something to withhold in these scenes
    from refspatial_gen.qa.verify_nesting import check_nesting as _check_nesting

    assert all(not _check_nesting(q) for q in pairs)


def test_verify_flags_a_nested_phrase(generated):
    from refspatial_gen.qa.verify_nesting import check_nesting as _check_nesting

    def relative(st):
        return isinstance((st.get("args") or {}).get("anchor"), dict) and "in" in st["args"]

    q = next(q for q in generated[0] if any(relative(st) for st in q.program))
    st = next(st for st in q.program if relative(st))
    st["args"]["anchor"]["phrase"] = "the box closest to the can"
    assert _check_nesting(q)


def test_no_template_chains_a_clause_after_an_anchor():
    # "the {cat} {r1.mod} {a1} that is {r2.sup} {a2}" and "the {cat} {rel.mod} {a} {near|at} {spot}" attach the
    # second clause to the anchor; "Is the {cat} that is {r1} {b} {r2} {c}?" reads {b} {r2} {c} as one phrase
    chained = re.compile(
        r"\{\w+\.mod\} \{\w+\} (that|which|\{near|\{at)"
        r"|(that|which)\|?\w*\}? is (between \{\w+\} and \{\w+\}|\{\w+\} \{\w+\}) \{\w+\} \{\w+\}"
    )
    bad = []
    for p in sorted(TEMPLATES.glob("*.yaml")):
        for fam in yaml.safe_load(p.read_text()).get("templates", []):
            for text in fam.get("text", []):
                if chained.search(text):
                    bad.append((p.name, fam["name"], text))
    assert not bad, bad
