"""A corner / edge free region's answer point lies at its corner / along its edge (graph/corner_point.py; verify's
own re-check qa/verify_spotpoint.py). Audit round 5: "the near-left corner of the cabinet" pointed at the patch's
inner corner, 46% of the way back from the front edge: the point farthest inside the patch is the one farthest
from the named corner."""

from __future__ import annotations

from types import SimpleNamespace

import numpy as np
from test_graph_helpers import box, camera, scene

from refspatial_gen.core.errors import RecipeError
from refspatial_gen.graph import build_graph
from refspatial_gen.graph.config import check_graph_section
from refspatial_gen.qa.verify_corners import check_corners
from refspatial_gen.qa.verify_spotpoint import check_spot_point

TABLE_CORNERS = {"near-left": (-0.6, -0.4), "near-right": (0.6, -0.4), "far-left": (-0.6, 0.4), "far-right": (0.6, 0.4)}
BIG_PATCH = {"thresholds": {"corner_size": 0.6}}  # corner patches half the table deep: their inner corner is far


def _frame():
    fr, _ = scene(("box", "red", box(0.0, 0.0)), cam=camera(eye=(0.0, -1.6, 0.75 + 1.0)))
    return fr


def _pair(region, point):
    struct = {"kind": "region", "region": region.to_json(), "points": [list(point)]}
    return SimpleNamespace(answer_struct=struct, program=[])


def test_corner_point_lies_at_its_corner() -> None:
    g = build_graph(_frame(), BIG_PATCH)
    corners = {r.label.removesuffix(" corner"): r for r in g.free_space if r.kind == "corner"}
    assert sorted(corners) == sorted(TABLE_CORNERS)
    for name, r in corners.items():
        c = np.array(TABLE_CORNERS[name])
        off = np.abs(np.array(r.point_world[:2]) - c)
        # the old point (the patch's most inner sample) lay ~0.2 m along both sides (0.28 m off the corner)
        assert np.linalg.norm(off) <= 0.1, (name, r.point_world)
        assert off[0] / 1.2 <= 0.25 and off[1] / 0.8 <= 0.25
        assert check_spot_point(_pair(r, r.point), _frame(), g) == []


def test_edge_point_lies_in_its_band() -> None:
    g = build_graph(_frame(), BIG_PATCH)
    edges = {r.label: r for r in g.free_space if r.kind == "edge"}
    assert {"near edge", "far edge", "left edge", "right edge"} <= set(edges)
    x, y = np.array(edges["near edge"].point_world[:2])
    assert (y + 0.4) / 0.8 <= 0.25
    x, y = np.array(edges["right edge"].point_world[:2])
    assert (0.6 - x) / 1.2 <= 0.25


def test_no_point_near_enough_withholds_the_region_and_counts_it() -> None:
    g = build_graph(_frame(), {"thresholds": {"corner_size": 0.6, "corner_point_max_share": 0.005}})
    assert not [r for r in g.free_space if r.kind in ("corner", "edge")]
    truth = g.meta["truth"]
    assert truth.get("corner_point_far") == 4 and truth.get("edge_point_far", 0) >= 1, truth
    assert any(r.kind == "left_of" for r in g.free_space)  # other regions are untouched


def test_verify_flags_a_point_far_from_its_corner() -> None:
    fr = _frame()
    g = build_graph(fr, BIG_PATCH)
    r = next(x for x in g.free_space if x.label == "near-left corner")
    inner = next(x for x in g.free_space if x.label == "near-right corner").point  # across the table
    probs = check_spot_point(_pair(r, inner), fr, g)
    assert probs and "near-left" in probs[0], probs
    assert any("near-left" in p for p in check_corners(_pair(r, inner), fr, g))  # verify's entry point calls it
    # a point inside the corner patch but 0.28 m (35% of the 0.8 m depth) back from the near side is flagged
    cam, G = fr.camera, np.array(g.meta["gravity"].get("rotation", np.eye(3)))
    uv, _ = cam.project((G.T @ np.array([-0.50, -0.12, r.z]))[None])
    old = (float(uv[0, 0]) / cam.width, float(uv[0, 1]) / cam.height)
    assert check_spot_point(_pair(r, old), fr, g), old


def test_share_must_be_a_share() -> None:
    errors: list[RecipeError] = []
    lines = {("graph", "thresholds", "corner_point_max_share"): 7}
    check_graph_section({"thresholds": {"corner_point_max_share": 1.5}}, "r.yaml", lines, errors)
    assert [str(e) for e in errors] == ["r.yaml:7: graph.thresholds.corner_point_max_share must be <= 1.0, got 1.5"]
