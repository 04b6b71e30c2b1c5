"""Look-alike stand-ins (truth/lookalikes.py; audit-pre sim:000018/v1:03, sim:000012/v0:04, sim:000001/v1:08):
a basket counts as a possible storage box, so "the storage box" is not unique beside one and "the leftmost
storage box" is not said of a box with a basket further left; verify re-derives the stand-ins a pair needs."""

from __future__ import annotations

import numpy as np
from test_graph_helpers import box, scene

from refspatial_gen.core.model import QAPair
from refspatial_gen.graph import build_graph
from refspatial_gen.graph.resolve import resolve_phrase
from refspatial_gen.qa.verify_lookalike import check_lookalikes
from refspatial_gen.truth.lookalikes import COUNT, add_lookalike_stand_ins, lookalikes


def _frame():
    fr, _ = scene(
        ("basket", "yellow", box(-0.3, 0.0)),
        ("storage box", "red", box(0.0, 0.0)),
        ("storage box", "blue", box(0.3, 0.0)),
    )
    return fr


def test_groups_are_symmetric_and_not_transitive():
    assert "basket" in lookalikes("storage box") and "storage box" in lookalikes("basket")
    assert {"glass", "wine glass", "mug"} <= lookalikes("cup")
    assert "mug" not in lookalikes("glass")  # a glass looks like a cup, a cup like a mug: not a glass like a mug
    assert lookalikes("banana") == frozenset()


def test_stand_ins_copy_mask_and_box_and_are_counted():
    fr = add_lookalike_stand_ins(_frame())
    extra = [o for o in fr.objects if o.provenance.get("distractor_only") == "lookalike"]
    # the basket may be a storage box; each storage box may be a basket
    assert sorted((o.provenance["stand_in_for"], o.category) for o in extra) == [
        (1, "storage box"),
        (2, "basket"),
        (3, "basket"),
    ]
    real = {o.id: o for o in fr.objects}
    for o in extra:
        src = real[o.provenance["stand_in_for"]]
        assert o.visible_fraction == 0.0 and o.mask.counts == src.mask.counts
        assert np.allclose(o.box.center, src.box.center) and o.id > 3
    assert fr.meta["truth"][COUNT] == 3
    assert add_lookalike_stand_ins(fr) is fr  # applied once


def test_leftmost_storage_box_counts_the_basket():
    old = _frame()
    g_old = build_graph(old, {"free_space": False})
    assert "the leftmost storage box" in g_old.node(2).phrases  # the old rule: the basket is not counted
    fr = add_lookalike_stand_ins(_frame())
    g = build_graph(fr, {"free_space": False})
    assert "the leftmost storage box" not in g.node(2).phrases
    assert "the leftmost storage box" not in g.node(1).phrases  # the basket is never named a storage box
    stand_ins = [n for n in g.nodes if n.object_id > 3]
    assert stand_ins and all(not n.phrases and n.point is None for n in stand_ins)  # below the floor: unnamed
    assert len(resolve_phrase("the leftmost storage box", fr)) == 1 and resolve_phrase(
        "the leftmost storage box", fr
    ) != [2]


def test_lone_storage_box_beside_a_basket_is_not_the_storage_box():
    fr, _ = scene(("basket", "yellow", box(-0.2, 0.0)), ("storage box", "green", box(0.2, 0.0)))
    assert "the storage box" in build_graph(fr, {"free_space": False}).node(2).phrases  # old: unique
    fr = add_lookalike_stand_ins(fr)
    g = build_graph(fr, {"free_space": False})
    assert "the storage box" not in g.node(2).phrases
    assert len(resolve_phrase("the storage box", fr)) == 2


def test_an_object_on_a_basket_stands_on_the_basket_not_its_stand_in():
    fr, _ = scene(
        ("basket", "yellow", box(0.0, 0.0, (0.2, 0.2, 0.1))),
        ("storage box", "red", box(0.3, 0.0)),
        ("apple", "red", box(0.0, 0.0, (0.06, 0.06, 0.06), z0=0.8)),
    )
    top = float(fr.object(1).box.center[2] + fr.object(1).box.size[2] / 2)
    apple = fr.object(3)
    apple.box = box(0.0, 0.0, (0.06, 0.06, 0.06), z0=top)
    g = build_graph(add_lookalike_stand_ins(fr), {"free_space": False})
    assert g.node(3).support == "obj:1"


def _pair(oid: int) -> QAPair:
    return QAPair(
        qa_id="t:0", frame_ids=["test"], family="locate", template="t", question="Where is the storage box?",
        answer="", answer_struct={"kind": "points", "object_ids": [oid]}, targets=[oid], relations=[],
        steps=1, image_size=(640, 480), program=[],
    )  # fmt: skip


def test_verify_needs_the_stand_ins_of_what_a_pair_names():
    bare = _frame()
    fr = add_lookalike_stand_ins(_frame())
    g = build_graph(fr, {"free_space": False})
    assert check_lookalikes(_pair(2), {"test": fr}, {"test": g}) == []
    bad = check_lookalikes(_pair(2), {"test": bare}, {"test": g})  # the shard lost the basket's stand-in
    assert bad and "object 1 (basket) looks like a storage box" in bad[0]
    g.meta["truth_floor"]["lookalike_stand_ins"] = 0  # the rule off: nothing to check
    assert check_lookalikes(_pair(2), {"test": bare}, {"test": g}) == []
