"""Corner and edge names only where a person sees them, at the top face's real extent (graph/surface_seen.py;
verify's own re-check qa/verify_corners.py). Audit round 4: a bed's "far-right corner" 0.3 m short of the
headboard (the declared surface stopped there, the mattress did not); "near the near-left corner of the floor"
with only a sliver of floor in view."""

from __future__ import annotations

import numpy as np

from refspatial_gen.core.camera import Camera, look_at
from refspatial_gen.core.geometry import Box3D
from refspatial_gen.core.mask import RLE
from refspatial_gen.core.model import Frame, ObjectInstance, QAPair, SupportSurface
from refspatial_gen.graph.builder import build_graph, geometry
from refspatial_gen.graph.relations.surface import surface_labels
from refspatial_gen.qa.verify_corners import check_corners
from refspatial_gen.sources.toy import raycast_boxes

W, H = 320, 240
F = W / (2 * np.tan(np.deg2rad(60) / 2))


def _frame(solids: list[Box3D], surfaces: list[SupportSurface], eye, target, objects=()) -> Frame:
    cam = Camera(W, H, F, F, W / 2, H / 2, look_at(np.array(eye, float), np.array(target, float)))
    depth, idx, _ = raycast_boxes(cam, solids)
    rgb = np.full((H, W, 3), 128, np.uint8)
    obs = []
    for k, b in objects:
        m = idx == k
        ys, xs = np.nonzero(m)
        obs.append(
            ObjectInstance(
                k, "bed", b, RLE.encode(m), (float(xs.min()), float(ys.min()), float(xs.max()), float(ys.max()))
            )
        )
    return Frame("t", rgb, depth, cam, obs, surfaces, source="toy", scene_id="t")


TABLE = Box3D(np.array([0.0, 0.0, 0.375]), np.array([1.2, 0.8, 0.75]), np.eye(3))
TABLE_VIEW = ([0.0, -1.0, 1.4], [0.0, 0.0, 0.75])


def _table_frame(declared: Box3D) -> Frame:
    return _frame([TABLE], [SupportSurface("table", "table", declared, None, "the table")], *TABLE_VIEW)


def _labels(frame: Frame) -> tuple[dict, dict]:
    geom = geometry(frame, {})
    e = surface_labels(geom)
    sid = frame.surfaces[0].id
    return e[sid], dict(geom.cache.get("truth", {}))


def test_table_seen_whole_keeps_every_corner() -> None:
    entry, truth = _labels(_table_frame(Box3D(np.array([0.0, 0.0, 0.74]), np.array([1.2, 0.8, 0.02]), np.eye(3))))
    assert sorted(entry["corners"]) == ["far-left", "far-right", "near-left", "near-right"]
    assert "surface_extent_continues" not in truth and "corner_unseen" not in truth


def test_top_face_going_on_past_the_declared_edge_withholds_that_side() -> None:
    # the declared surface is the table's left 0.8 m: its top visibly goes on 0.4 m past the right side
    short = Box3D(np.array([-0.2, 0.0, 0.74]), np.array([0.8, 0.8, 0.02]), np.eye(3))
    frame = _table_frame(short)
    entry, truth = _labels(frame)
    assert "far-right" not in entry["corners"] and "near-right" not in entry["corners"]
    assert "right edge" not in entry["edges"]
    assert "far-left" in entry["corners"] and "near-left" in entry["corners"]
    assert truth.get("surface_extent_continues", 0) >= 3
    graph = build_graph(frame, {})
    assert graph.meta["truth"]["surface_extent_continues"] == truth["surface_extent_continues"]
    assert all(r.label != "far-right corner" for r in graph.free_space)
    # verify's own code flags a pair that still names the continuing corner, and passes the honest one
    assert check_corners(_spot_pair("corner", "table", "far-right"), frame, graph)
    assert not check_corners(_spot_pair("corner", "table", "far-left"), frame, graph)


FLOOR = Box3D(np.array([0.0, 0.6, -0.01]), np.array([2.0, 2.0, 0.02]), np.eye(3))
FLOOR_VIEW = ([0.0, -2.0, 1.6], [0.0, 0.4, 0.0])
BED = Box3D(np.array([-0.55, 0.05, 0.3]), np.array([1.0, 1.0, 0.6]), np.eye(3))


def _floor_frame(with_bed: bool) -> Frame:
    solids = [FLOOR] + ([BED] if with_bed else [])
    surfaces = [SupportSurface("floor", "floor", FLOOR, None, "the floor")]
    return _frame(solids, surfaces, *FLOOR_VIEW, objects=[(1, BED)] if with_bed else [])


def test_floor_corner_hidden_by_a_bed_is_withheld() -> None:
    open_entry, open_truth = _labels(_floor_frame(False))
    assert "near-left" in open_entry["corners"], open_entry  # control: seen when nothing hides it
    frame = _floor_frame(True)
    entry, truth = _labels(frame)
    assert "near-left" not in entry["corners"]
    assert "near-right" in entry["corners"]  # the rest of the floor is still seen
    assert truth.get("corner_unseen", 0) > open_truth.get("corner_unseen", 0)
    graph = build_graph(frame, {})
    assert check_corners(_spot_pair("corner", "floor", "near-left"), frame, graph)
    assert not check_corners(_spot_pair("corner", "floor", "near-right"), frame, graph)


def test_scan_floor_slab_corners_out_of_view_are_withheld() -> None:
    # a scan's floor is a 30 m slab around the camera: its corners are never in the picture
    slab = Box3D(np.array([0.0, -2.0, -0.01]), np.array([30.0, 30.0, 0.02]), np.eye(3))
    frame = _frame([slab], [SupportSurface("floor", "floor", slab, None, "the floor")], *FLOOR_VIEW)
    entry, truth = _labels(frame)
    assert entry["corners"] == {} and entry["edges"] == {}
    assert truth.get("corner_unseen", 0) + truth.get("surface_extent_continues", 0) >= 1


def _spot_pair(kind: str, sid: str, name: str) -> QAPair:
    step = {"op": "is_at", "as": "step1", "args": {"a": {"object": 1}, "spot": {"spot": [kind, sid, name]}}}
    return QAPair("q", "choice", "t", "?", "(A) yes", {"kind": "choice"}, [kind], 2, ["t"], (W, H), [step])


def test_sim_bed_surface_is_the_mattress_top_to_the_headboard() -> None:
    from types import SimpleNamespace

    from refspatial_gen.sources.sim import furniture as F
    from refspatial_gen.sources.sim.layout import Surface

    b = SimpleNamespace(rng=np.random.default_rng(3), statics=[], surfaces=[])
    floor = Surface("floor", "floor", "the floor", np.zeros(2), np.array([2.5, 2.0]), 0.0, 0.0)
    (bed,) = F.bed(b, floor, 0.0)
    mattress = next(s for s in b.statics if s.name == "bed_mattress")
    head = next(s for s in b.statics if s.name == "bed_head")
    cx, cy, hx, hy = bed.face
    # the face reaches the headboard and the mattress's foot and sides, not the smaller placement area
    assert abs((cy + hy) - (head.center[1] - head.half[1])) < 1e-9
    assert abs((cy - hy) - (mattress.center[1] - mattress.half[1])) < 1e-9
    assert abs(hx - mattress.half[0]) < 1e-9
    assert bed.center[1] + bed.half[1] < cy + hy - 0.2  # objects still keep off the pillow end
