"""A camera turn to face an object only for a target seen whole (qa/recognisable.py ROTATION_CUT, verify:
qa/verify_truth.py). Audit round 5: "rotate left around 3.0 degrees to face the train" for a train running past
both edges of the photo: its centre is nowhere a person can point to."""

from __future__ import annotations

from refspatial_gen.graph import build_graph
from refspatial_gen.qa.recognisable import ROTATION_CUT, ROTATION_RELATIONS
from refspatial_gen.qa.verify_truth import check_truth
from tests.test_recog_floor import _cut_scene, _many, _scene, cfg  # noqa: F401  (cfg: a fixture)


def _turns(qas):
    return [q for q in qas if not ROTATION_RELATIONS.isdisjoint(q.relations) and q.targets]


def test_no_camera_turn_to_face_an_object_cut_by_the_border(cfg):  # noqa: F811
    f = _cut_scene()
    g = build_graph(f)
    assert g.node(3).attributes["sized"] is False
    qas, truth = _many(f, g, cfg, n=24)
    turns = _turns(qas)
    assert turns, "the scene gives camera-turn questions about the whole objects"
    assert all(3 not in q.targets for q in turns), [q.question for q in turns if 3 in q.targets]
    assert truth.get(ROTATION_CUT, 0) > 0


def test_verify_fails_a_camera_turn_to_a_cut_object(cfg):  # noqa: F811
    f = _scene()
    g = build_graph(f)
    qas, _ = _many(f, g, cfg, n=24)
    turns = [q for q in _turns(qas) if 3 in q.targets]
    assert turns, "uncut, the green can is a target of camera turns"
    assert check_truth(turns[0], {f.frame_id: f}, {f.frame_id: g}) == []
    cut = _cut_scene()
    problems = check_truth(turns[0], {cut.frame_id: cut}, {cut.frame_id: g})
    assert any("camera turn" in p and "border" in p for p in problems), problems
