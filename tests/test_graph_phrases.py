"""Referring phrases: every phrase the graph emits resolves, by the independent resolver
(graph/resolve.py, which parses the text and measures the scene itself), to exactly its object."""

from __future__ import annotations

import numpy as np
from hypothesis import given, settings
from hypothesis import strategies as st
from test_graph_helpers import box, scene

from refspatial_gen.core.mask import denormalise_point
from refspatial_gen.graph import build_graph
from refspatial_gen.graph.resolve import resolve_phrase, resolver
from refspatial_gen.sources.toy import toy_frame


@settings(max_examples=25, deadline=None)
@given(seed=st.integers(0, 2**31 - 1), n=st.integers(2, 12))
def test_every_phrase_resolves_to_exactly_its_object(seed, n):
    frame = toy_frame(np.random.default_rng(seed), n, 256, 192)
    graph = build_graph(frame, {"free_space": False})
    by_frame, by_graph = resolver(frame), resolver(graph)
    masks = {o.id: o.mask.decode() for o in frame.objects}
    for node in graph.nodes:
        for p in node.phrases:
            assert by_frame(p) == [node.object_id], f"{p!r} -> {by_frame(p)} (object {node.object_id})"
            assert by_graph(p) == [node.object_id], f"{p!r} (graph) -> {by_graph(p)}"
        # shortest first
        lengths = [len(p.split()) for p in node.phrases]
        assert lengths == sorted(lengths)
        # answer point inside the object's visible mask (none, and no phrase, below the visibility floor)
        if node.point is None:
            assert not node.phrases and node.attributes.get("below_floor")
            continue
        x, y = denormalise_point(*node.point, frame.camera.width, frame.camera.height)
        assert masks[node.object_id][y, x]


def test_resolver_reports_ambiguity():
    # two red boxes side by side (same size), a blue can: "the box" and "the red box" are ambiguous
    fr, _ = scene(
        ("box", "red", box(-0.2, 0.0)),
        ("box", "red", box(0.2, 0.0)),
        ("can", "blue", box(0.0, 0.2, (0.06, 0.06, 0.12))),
    )
    assert resolve_phrase("the box", fr) == [1, 2]
    assert resolve_phrase("the red box", fr) == [1, 2]
    assert resolve_phrase("the leftmost box", fr) == [1]
    assert resolve_phrase("the can", fr) == [3]
    assert resolve_phrase("the green box", fr) == []
    assert resolve_phrase("a box", fr) == []
    g = build_graph(fr, {"free_space": False})
    phrases = {n.object_id: n.phrases for n in g.nodes}
    assert "the box" not in phrases[1] and "the red box" not in phrases[1]
    assert "the leftmost box" in phrases[1] and "the rightmost box" in phrases[2]
    # nearly level boxes (within the margin): neither gets "leftmost"; the resolver sees both
    fr, _ = scene(("box", "red", box(0.0, -0.1)), ("box", "red", box(0.004, 0.2)))
    assert resolve_phrase("the leftmost box", fr) == [1, 2]
    g = build_graph(fr, {"free_space": False})
    assert all("leftmost" not in p for n in g.nodes for p in n.phrases)


def test_superlatives_ordinals_and_anchor_phrases():
    fr, _ = scene(
        ("can", "red", box(-0.3, 0.0, (0.06, 0.06, 0.30))),
        ("can", "red", box(-0.1, 0.0, (0.06, 0.06, 0.10))),
        ("can", "red", box(0.1, 0.0, (0.06, 0.06, 0.16))),
        ("tray", "blue", box(0.3, 0.0, (0.20, 0.15, 0.02))),
    )
    g = build_graph(fr, {"free_space": False})
    ph = {n.object_id: n.phrases for n in g.nodes}
    assert "the tallest can" in ph[1] and "the shortest can" in ph[2]
    assert "the second can from the left" in ph[2]
    assert "the can closest to the tray" in ph[3]
    for oid, plist in ph.items():
        for p in plist:
            assert resolve_phrase(p, fr) == [oid]


def test_stacked_object_gets_an_on_phrase():
    fr, _ = scene(
        ("block", "red", box(0.0, 0.0, (0.05, 0.05, 0.05), z0=0.75 + 0.02)),
        ("tray", "blue", box(0.0, 0.0, (0.20, 0.15, 0.02))),
        ("block", "red", box(0.3, 0.0, (0.05, 0.05, 0.05))),
    )
    # a 192x144 test image: the blocks have ~80 pixels, so the visibility floor is off for this grammar test
    g = build_graph(fr, {"free_space": False, "truth": {"min_visible_px": 0}})
    assert "the block on the tray" in g.node(1).phrases
    assert resolve_phrase("the block on the tray", fr) == [1]
    # the stacked block is also within the support gap of the table top: "on the table" is ambiguous
    assert resolve_phrase("the block on the table", fr) == [1, 3]
    assert all("on the table" not in p for n in g.nodes for p in n.phrases)


def test_hidden_object_gets_no_phrase_but_still_counts():
    from refspatial_gen.core.mask import RLE

    fr, _ = scene(
        ("box", "red", box(-0.2, 0.0)),
        ("box", "blue", box(0.2, 0.0)),
        ("can", "green", box(0.0, 0.2, (0.06, 0.06, 0.12))),
    )
    fr.objects[1].mask = RLE.encode(np.zeros((fr.camera.height, fr.camera.width), bool))  # box 2 not visible
    g = build_graph(fr, {"free_space": False})
    assert g.node(2).point is None and g.node(2).phrases == []
    assert "the box" not in g.node(1).phrases  # box 2 is still in the scene
    assert all("blue" not in p for n in g.nodes for p in n.phrases)  # never used as an anchor either
    for n in g.nodes:
        for p in n.phrases:
            assert resolve_phrase(p, fr) == [n.object_id]


def test_closest_to_needs_a_relative_gap_a_person_sees():
    """'the can closest to the tray' only when the runner-up is clearly farther (distance_margin_rel of its
    distance), not merely beyond the absolute anchor margin: 0.40 m vs 0.45 m to the tray is too close to call
    (round-2 audit: near-equal distances); fails on the old code, which used the absolute margin only."""
    fr, _ = scene(
        ("can", "red", box(-0.35, 0.0, (0.06, 0.06, 0.12))),
        ("can", "red", box(0.50, 0.0, (0.06, 0.06, 0.12))),
        ("tray", "blue", box(0.05, 0.0, (0.16, 0.16, 0.06))),
    )
    g = build_graph(fr, {"free_space": False})
    d = {n.object_id: n.phrases for n in g.nodes}
    assert not any("closest to" in p or "farthest from" in p for p in d[1] + d[2])
    fr2, _ = scene(
        ("can", "red", box(-0.45, 0.0, (0.06, 0.06, 0.12))),
        ("can", "red", box(0.20, 0.0, (0.06, 0.06, 0.12))),
        ("tray", "blue", box(0.35, 0.0, (0.10, 0.10, 0.02))),
    )
    ph = {n.object_id: n.phrases for n in build_graph(fr2, {"free_space": False}).nodes}
    assert "the can closest to the tray" in ph[2] and "the can farthest from the tray" in ph[1]
    for oid, plist in ph.items():
        for p in plist:
            assert resolve_phrase(p, fr2) == [oid]
