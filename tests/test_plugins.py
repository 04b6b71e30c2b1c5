"""Extension points from test code alone: a toy relation and a toy step op, each one registration, used by a
template to generate QA pairs that `verify` accepts. If adding either needed an edit anywhere else in the
package, this test could not be written."""

from __future__ import annotations

from collections.abc import Collection, Iterator
from typing import Any

import numpy as np
import pytest

from refspatial_gen.core.model import RelationFact, Sample
from refspatial_gen.graph.relations import REGISTRY, register
from refspatial_gen.graph.relations.base import Cell, Relation
from refspatial_gen.graph.relations.common import pos
from refspatial_gen.qa import generate_qa, verify_sample
from refspatial_gen.qa.config import Family, QAConfig
from refspatial_gen.qa.index import Reject
from refspatial_gen.qa.ops import OPS, SET, Arg, Op
from refspatial_gen.qa.ops.common import bounded, resolve, set_in
from refspatial_gen.qa.templates import compile_templates
from tests.helpers.scenes import toy_scenes


# ---------------------------------------------------------------- a toy relation: same colour (from node attributes)
def _same_colour_geometry(geom: Any, a: int, b: int) -> RelationFact:
    ca, cb = geom.colours[pos(geom, a)], geom.colours[pos(geom, b)]
    holds = None if ca is None or cb is None else ca == cb
    return RelationFact("same_colour", (a, b), holds, float(holds or 0.0), 0.0)


def _same_colour_cell(t: Any, args: tuple[Any, ...]) -> Cell | None:
    ca, cb = (t.nodes[x].attributes.get("color") for x in args)
    holds = None if ca is None or cb is None else ca == cb
    return Cell(holds, float(holds or 0.0), 0.0)


TOY_RELATION = Relation(
    "same_colour",
    "toy",
    "obj",
    2,
    "1 when the colour words agree",
    "",
    "A has B's colour word",
    storage="derived",
    spec=False,
    qa="pairwise",
    evaluate=_same_colour_geometry,
    cell=_same_colour_cell,
)


# ---------------------------------------------------------------- a toy op: keep the objects for which a relation fails
class Exclude(Op):
    name = "exclude"
    args = {"in": Arg("set"), "relation": Arg("relation", True), "anchor": Arg("object", True)}
    out = SET
    relation_uses = ("pairwise",)
    doc = "keep objects x for which relation(x, anchor) is false (anchor + phrase: 2 steps)"
    narrowing = chain = droppable = True

    def weight(self, present: Collection[str]) -> int:
        return 2

    def run(self, st: Any, env: dict[str, Any], prev: Any, ctx: Any) -> Any:
        idx = ctx.idx
        s = set_in(st, env, prev, idx)
        rel, anchor = resolve(st.args["relation"], env, prev, idx), resolve(st.args["anchor"], env, prev, idx)
        true, undecided, missing = idx.rel_entry(rel, anchor)
        if not undecided.isdisjoint(s) or not missing.isdisjoint(s):
            raise Reject("margin")
        return bounded(st, s, frozenset(x for x in s if x != anchor and x not in true), ctx)

    def verify(self, run: Any, a: dict[str, Any], prev: Any, st: dict[str, Any]) -> Any:
        anchor = a["anchor"]
        return frozenset(x for x in run.input_set(a) if x != anchor and not run.w.holds(a["relation"], x, anchor))


TEMPLATE = {
    "templates": [
        {
            "name": "left_not_same_colour",
            "slots": {
                "b": "anchor",
                "a": "anchor",
                "col": {"type": "relation", "choices": ["same_colour"], "phrases": {"same_colour": "the colour of"}},
            },
            "program": [
                {"op": "relate", "relation": "left", "anchor": "b"},
                {"op": "exclude", "relation": "col", "anchor": "a"},
                {"op": "locate"},
            ],
            "text": ["Point to the object left of {b} that is not {col} {a}."],
        }
    ]
}


@pytest.fixture()
def plugins() -> Iterator[None]:
    register(TOY_RELATION)  # one registration each
    OPS.add("exclude", Exclude())
    try:
        yield
    finally:
        REGISTRY.remove("same_colour")
        OPS.remove("exclude")


def test_toy_relation_and_op_generate_verified_questions(plugins: None) -> None:
    errors: list[Any] = []
    templates = compile_templates(TEMPLATE, "toy.yaml", {}, errors)
    assert not errors and templates[0].n_steps == 4
    templates = [t.__class__(**{**t.__dict__, "family": "toy"}) for t in templates]
    config = QAConfig([Family("toy", 1.0, templates)], max_per_sample=3)
    made = 0
    for k, (f, g) in enumerate(toy_scenes(range(200, 212), 8)):
        qa = generate_qa([f], [g], np.random.default_rng(k), config)
        made += len(qa)
        for q in qa:
            assert q.template == "toy/left_not_same_colour" and "same_colour" in q.relations
            assert [s["op"] for s in q.program] == ["relate", "exclude", "locate"]
            assert "is not the colour of" in q.question
        sample = Sample(sample_id=f"s{k}", frames=[f], graphs=[g], qa=qa, unit_key=f"u{k}", meta={})
        assert verify_sample(sample) == []
    assert made >= 5
