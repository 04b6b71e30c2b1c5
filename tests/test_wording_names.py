"""Category names that clash with the questions' own words: the simulated catalog's "camera" is a photo
camera in every phrase and question ("the camera" is the viewpoint: "closest to the camera")."""

from __future__ import annotations

import numpy as np
from test_graph_helpers import box, scene

from refspatial_gen.graph import build_graph
from refspatial_gen.graph.resolve import resolve_phrase
from refspatial_gen.qa import generate_qa
from refspatial_gen.qa.bench import default_config


def test_camera_object_is_named_photo_camera():
    fr, _ = scene(
        ("camera", "black", box(-0.2, 0.0, (0.12, 0.07, 0.08))),
        ("can", "red", box(0.1, 0.0, (0.06, 0.06, 0.12))),
        ("can", "blue", box(0.25, 0.1, (0.06, 0.06, 0.12))),
    )
    g = build_graph(fr)
    cam = g.node(1)
    assert cam.phrases and all(p.startswith("the photo camera") or "photo camera" in p for p in cam.phrases)
    assert not any(p == "the camera" or p.endswith(" the camera") for n in g.nodes for p in n.phrases)
    assert resolve_phrase("the photo camera", fr) == [1] and resolve_phrase("the photo camera", g) == [1]
    qs = []
    for k in range(6):
        qs += generate_qa([fr], [g], np.random.default_rng(k), default_config())
    assert any("photo camera" in q.question for q in qs)
    for q in qs:  # a question about the camera object calls it the photo camera
        for st in q.program:
            a = st.get("args") or {}
            if a.get("category") == "camera":
                assert "photo camera" in q.question.lower(), q.question
