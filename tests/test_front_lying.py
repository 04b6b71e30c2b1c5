"""Fronts of objects lying flat (graph/visibility.py `min_front_height_ratio`, qa/verify_truth.py): a book lying
on the table has no facing a person can judge (audit round 3, ycb/0/sim:000011/v0:00 "Check whether the book is
facing the mustard bottle"): its front is withheld (front_withheld_lying); standing, it keeps it; verify agrees."""

from __future__ import annotations

from refspatial_gen.graph import build_graph
from refspatial_gen.graph.visibility import FRONT_LYING, Floor
from refspatial_gen.qa.verify_truth import check_truth
from tests.test_recog_floor import _box, _many, _scene, _with, cfg  # noqa: F401  (cfg: a fixture)


def test_book_lying_flat_has_no_front_but_standing_keeps_it():
    assert Floor().min_front_height_ratio == 0.4
    g = build_graph(_scene())  # the book: 0.18 x 0.14 x 0.03 m, lying on the table
    a = g.node(4).attributes
    assert "below_floor" not in a and a["front"] is None and a["front_check"] == FRONT_LYING
    assert g.meta["truth"][FRONT_LYING] == 1
    assert g.node(1).attributes["front"] is not None  # a can (0.12 m tall, 0.065 m wide) keeps its front
    standing = build_graph(_with(_scene(), 4, box=_box(0.0, -0.2, 0.04, 0.14, 0.2)))
    assert standing.node(4).attributes.get("front") is not None


def test_verify_flags_a_pair_reading_the_front_of_a_lying_book(cfg):  # noqa: F811
    """Pairs generated with the rule off that read the book's front fail verify against the default floor."""
    f = _scene()
    off = build_graph(f, {"truth": {"min_front_height_ratio": 0.0}})
    assert off.node(4).attributes["front"] is not None
    pairs, _ = _many(f, off, cfg, n=12)
    floor = build_graph(f).meta["truth_floor"]
    off.meta["truth_floor"] = floor
    flagged = [p for q in pairs for p in check_truth(q, {f.frame_id: f}, {f.frame_id: off}) if "lying flat" in p]
    assert flagged and all("object 4 (book)" in p for p in flagged)
    on = build_graph(f)
    for q in _many(f, on, cfg, n=12)[0]:
        assert not [p for p in check_truth(q, {f.frame_id: f}, {f.frame_id: on}) if "lying flat" in p]
