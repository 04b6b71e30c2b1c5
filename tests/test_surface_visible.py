"""A surface is named (free space, corners, edges) only when a person can see its top (graph/surface_visible.py;
verify's own re-check qa/verify_surface_seen.py). Audit round 5 (ycb sim:000023 #8): "a free place at the far
edge of the bottom shelf" on a shelf seen as a strip a few pixels deep."""

from __future__ import annotations

from typing import Any

import numpy as np

from refspatial_gen.core.geometry import Box3D
from refspatial_gen.core.mask import RLE
from refspatial_gen.core.model import Frame, ObjectInstance, QAPair, SupportSurface
from refspatial_gen.graph.builder import build_graph
from refspatial_gen.graph.config import check_graph_section
from refspatial_gen.qa.verify_corners import check_corners
from tests.test_surface_seen import TABLE, H, W, _frame, _table_frame

TABLE_TOP = Box3D(np.array([0.0, 0.0, 0.74]), np.array([1.2, 0.8, 0.02]), np.eye(3))


def _shelf_frame(top: float) -> Frame:
    """A shelf whose top (1.0 x 0.4 m) lies just under the eye: seen at a grazing angle."""
    body = Box3D(np.array([0.0, 0.6, top / 2]), np.array([1.0, 0.4, top]), np.eye(3))
    slab = Box3D(np.array([0.0, 0.6, top - 0.01]), np.array([1.0, 0.4, 0.02]), np.eye(3))
    return _frame([body], [SupportSurface("shelf", "shelf", slab, None, "the shelf")], [0.0, -1.0, 1.4], [0, 0.6, 1])


def _region_pair(sid: str, kind: str = "edge", label: str = "far edge") -> QAPair:
    region = {"region": {"kind": kind, "label": label, "surface_id": sid, "anchors": []}}
    step = {"op": "free_space", "as": "step1", "args": {"region": region}}
    return QAPair("q", "point", "t", "?", "[(0.5, 0.5)]", {"kind": "region"}, [kind], 1, ["t"], (W, H), [step])


def test_shelf_seen_as_a_strip_gets_no_placement_region() -> None:
    frame = _shelf_frame(1.30)  # its seen top: ~4 px deep at 320x240 (min_surface_rows 12 at 640x480 -> 6)
    graph = build_graph(frame, {})
    assert [r for r in graph.free_space if r.surface_id == "shelf"] == []
    assert graph.meta["surfaces"]["shelf"]["corners"] == [] and graph.meta["surfaces"]["shelf"]["edges"] == []
    assert graph.meta["truth"]["surface_sliver"] == 1
    # verify's own code flags a pair that still names the shelf
    problems = check_corners(_region_pair("shelf"), frame, graph)
    assert problems and "deep" in problems[0]


def test_shelf_top_hardly_in_the_picture_is_unseen() -> None:
    frame = _shelf_frame(1.36)
    graph = build_graph(frame, {})
    assert graph.meta["truth"]["surface_unseen"] == 1
    assert [r for r in graph.free_space if r.surface_id == "shelf"] == []
    assert "surface shelf" in check_corners(_region_pair("shelf"), frame, graph)[0]


def test_table_top_seen_well_keeps_its_regions() -> None:
    frame = _table_frame(TABLE_TOP)
    graph = build_graph(frame, {})
    kinds = {r.kind for r in graph.free_space if r.surface_id == "table"}
    assert {"corner", "edge"} <= kinds
    truth = graph.meta.get("truth", {})
    assert not {"surface_unseen", "surface_sliver", "surface_object_below_floor"} & set(truth)
    assert check_corners(_region_pair("table"), frame, graph) == []


def test_surface_of_an_object_below_the_floor_is_not_named() -> None:
    def frame(visible: float) -> Frame:
        f = _table_frame(TABLE_TOP)
        m = np.zeros((H, W), bool)
        m[H // 2 :, :] = True
        f.rgb[m] = (150, 90, 40)  # a brown table on grey: it passes the contrast floor
        f.objects.append(ObjectInstance(1, "table", TABLE, RLE.encode(m), (0.0, H / 2, W, H), visible))
        f.surfaces[0] = SupportSurface("table", "table", TABLE_TOP, 1, "the table")
        return f

    seen = build_graph(frame(1.0), {})
    assert any(r.surface_id == "table" for r in seen.free_space)  # control: the object passes the floor
    hidden = frame(0.2)  # visible fraction 0.2 < min_visible_fraction 0.5
    graph = build_graph(hidden, {})
    assert graph.meta["truth"]["surface_object_below_floor"] == 1
    assert [r for r in graph.free_space if r.surface_id == "table"] == []
    assert "below the object floor" in check_corners(_region_pair("table"), hidden, graph)[0]


def test_thresholds_are_recipe_keys() -> None:
    frame = _table_frame(TABLE_TOP)
    strict = build_graph(frame, {"thresholds": {"min_surface_rows": 400.0}})
    assert strict.meta["truth"]["surface_sliver"] == 1 and strict.free_space == []
    errors: list[Any] = []
    check_graph_section({"thresholds": {"min_surface_px": 1500, "min_surface_rows": 12}}, "r.yaml", {}, errors)
    assert errors == []
    check_graph_section({"thresholds": {"min_surface_px": -1, "min_surface_rows": "deep"}}, "r.yaml", {}, errors)
    assert len(errors) == 2 and all("r.yaml" in str(e) for e in errors)
