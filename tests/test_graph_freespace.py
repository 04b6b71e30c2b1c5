"""Free space: every answer point lies on its support surface, outside every obstacle footprint, inside
the image and passes the depth-visibility test; planted violations are caught by check_free_point."""

from __future__ import annotations

import numpy as np
import pytest
import shapely
from shapely.geometry import Polygon
from test_graph_helpers import box, camera, scene

from refspatial_gen.core.mask import normalise_point
from refspatial_gen.core.model import FreeSpaceRegion
from refspatial_gen.graph import build_graph
from refspatial_gen.graph.freespace import check_free_point
from refspatial_gen.sources.toy import toy_frame


@pytest.fixture(scope="module")
def toy_graphs():
    out = []
    for seed in range(6):
        f = toy_frame(np.random.default_rng(100 + seed), 8, 320, 240, frame_id=f"fs{seed}")
        out.append((f, build_graph(f)))
    return out


def test_every_region_point_is_valid(toy_graphs):
    kinds = set()
    n = 0
    for frame, graph in toy_graphs:
        for r in graph.free_space:
            n += 1
            kinds.add(r.kind)
            assert check_free_point(frame, graph, r) == [], (r.kind, r.anchors, check_free_point(frame, graph, r))
            assert r.area >= graph.meta["thresholds"]["free_min_area"]
            assert Polygon(r.polygon_xy).is_valid
            assert shapely.contains_xy(Polygon(r.polygon_xy), r.point_world[0], r.point_world[1])
    assert n >= 30
    assert {"left_of", "right_of", "in_front_of", "behind", "corner", "edge"} <= kinds


def _first(graph, kind):
    return next(r for r in graph.free_space if r.kind == kind)


def test_planted_violations_are_caught(toy_graphs):
    frame, graph = toy_graphs[0]
    r = _first(graph, "right_of")
    # outside the image
    assert any("outside the image" in p for p in check_free_point(frame, graph, r, (1.2, 0.5)))
    # on an object: the object's own answer point (occludes the table, and lies on its footprint)
    obj = graph.nodes[0]
    probs = check_free_point(frame, graph, r, obj.point)
    assert any("obstacle" in p for p in probs) or any("not visible" in p for p in probs)
    assert any("not visible" in p for p in probs)
    # off the table: the top-left image corner sees the background
    probs = check_free_point(frame, graph, r, (0.001, 0.001))
    assert probs and (any("off surface" in p for p in probs) or any("does not see" in p for p in probs))
    # a different region's point is outside this region
    other = (
        next(x for x in graph.free_space if x.kind == "left_of" and x.anchors == r.anchors)
        if any(x.kind == "left_of" and x.anchors == r.anchors for x in graph.free_space)
        else _first(graph, "corner")
    )
    assert any("outside the region" in p for p in check_free_point(frame, graph, r, other.point))


def test_obstacle_footprint_caught_even_where_visible():
    # a flat 1 cm mat lies on the table: its top is within the visibility tolerance of the table plane,
    # so only the footprint test can catch a point placed on it
    fr, _ = scene(("box", "red", box(-0.3, 0.0)), ("tray", "blue", box(0.15, 0.0, (0.25, 0.2, 0.01))))
    g = build_graph(fr)
    r = next(x for x in g.free_space if x.kind == "right_of" and x.anchors == (1,))
    mat = g.node(2).point
    probs = check_free_point(fr, g, r, mat)
    assert any("obstacle" in p for p in probs), probs
    # and no region point lies on the mat
    for x in g.free_space:
        assert check_free_point(fr, g, x) == []


def test_occluded_surface_point_is_not_visible():
    # a tall box in front hides the table behind it; a point on the table behind it is occluded
    fr, _ = scene(("box", "red", box(0.0, -0.1, (0.2, 0.05, 0.35))), ("can", "blue", box(0.4, 0.3, (0.06, 0.06, 0.12))))
    g = build_graph(fr)
    cam = fr.camera
    hidden = np.array([0.0, 0.05, 0.75])  # on the table, right behind the box
    uv, _ = cam.project(hidden[None])
    p = normalise_point(float(np.floor(uv[0, 0])), float(np.floor(uv[0, 1])), cam.width, cam.height)
    fake = FreeSpaceRegion(
        "table", "behind", (1,), [(-0.3, 0.0), (0.3, 0.0), (0.3, 0.2), (-0.3, 0.2)], 0.75, 0.1, tuple(hidden), p, ""
    )
    probs = check_free_point(fr, g, fake)
    assert any("not visible" in q for q in probs), probs
    for x in g.free_space:
        assert check_free_point(fr, g, x) == []


def test_regions_respect_sector_directions():
    far_cam = camera(eye=(0.0, -1.6, 0.75 + 1.0))  # the whole table in view
    fr, _ = scene(("box", "red", box(0.0, 0.0)), cam=far_cam)
    g = build_graph(fr)
    c = np.array([0.0, 0.0])
    got = {r.kind: np.array(r.point_world[:2]) - c for r in g.free_space if r.anchors == (1,)}
    assert {"left_of", "right_of", "in_front_of", "behind"} <= set(got)
    assert got["left_of"][0] < -abs(got["left_of"][1]) * 0.99
    assert got["right_of"][0] > abs(got["right_of"][1]) * 0.99
    assert got["in_front_of"][1] < -abs(got["in_front_of"][0]) * 0.99  # towards the camera (-y)
    assert got["behind"][1] > abs(got["behind"][0]) * 0.99
    labels = {r.label for r in g.free_space if r.kind in ("corner", "edge")}
    assert {
        "near-left corner",
        "near-right corner",
        "far-left corner",
        "far-right corner",
        "left edge",
        "right edge",
        "near edge",
        "far edge",
    } <= labels
