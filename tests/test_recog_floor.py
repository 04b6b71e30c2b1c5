"""Recognisability floor (graph/visibility.py, qa/recognisable.py, graph/freespace.py, qa/verify_truth.py):
half-hidden objects and slivers are never named, objects cut by the border get no size question and no front,
free-space points keep clear of every object and the border; verify re-checks each from the stored data."""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest

from refspatial_gen.core.geometry import Box3D
from refspatial_gen.core.mask import RLE
from refspatial_gen.core.model import Sample
from refspatial_gen.graph import build_graph
from refspatial_gen.graph.visibility import Floor, px_scale
from refspatial_gen.qa import generate_qa
from refspatial_gen.qa.recognisable import SIZE_CUT, SIZE_RELATIONS
from refspatial_gen.qa.verify import verify_sample
from refspatial_gen.qa.verify_truth import check_truth, named_objects
from refspatial_gen.recipe import load_recipe
from refspatial_gen.sources.toy import TABLE, toy_frame

TOP = TABLE.top_z


def _box(x: float, y: float, sx: float, sy: float, h: float) -> Box3D:
    return Box3D(np.array([x, y, TOP + h / 2]), np.array([sx, sy, h]), np.eye(3))


def _scene():
    boxes = [
        ("can", "red", _box(-0.3, 0.0, 0.065, 0.065, 0.12)),
        ("can", "blue", _box(-0.1, 0.05, 0.065, 0.065, 0.10)),
        ("can", "green", _box(0.1, 0.0, 0.065, 0.065, 0.13)),
        ("book", "yellow", _box(0.0, -0.2, 0.18, 0.14, 0.03)),
        ("box", "white", _box(0.3, 0.1, 0.1, 0.1, 0.08)),
    ]
    return toy_frame(np.random.default_rng(0), boxes=boxes, width=640, height=480)


def _with(frame, oid, **changes):
    """The frame with object `oid` changed. A new mask is also painted into the image (the object's colour on
    its new pixels, the table's on the pixels it gave up), so the picture shows what the mask says and the
    contrast floor (graph/contrast.py) sees the object these tests describe."""
    if "mask" in changes and frame.rgb is not None:
        old = next(o for o in frame.objects if o.id == oid).mask.decode().astype(bool)
        new = changes["mask"].decode().astype(bool)
        anyone = np.zeros_like(old)
        for o in frame.objects:
            anyone |= o.mask.decode().astype(bool)
        rgb = np.array(frame.rgb)
        colour, table = np.median(rgb[old], axis=0), np.median(rgb[~anyone], axis=0)
        rgb[old & ~new] = table.astype(rgb.dtype)
        rgb[new] = colour.astype(rgb.dtype)
        frame = dataclasses.replace(frame, rgb=rgb)
    return dataclasses.replace(
        frame, objects=[dataclasses.replace(o, **changes) if o.id == oid else o for o in frame.objects]
    )


@pytest.fixture(scope="module")
def cfg():
    return load_recipe("recipes/default.yaml").qa


def _many(f, g, cfg, n=10):
    truth: dict[str, int] = {}
    out = []
    for seed in range(n):
        out += generate_qa([f], [g], np.random.default_rng(seed), cfg, truth=truth)
    return out, truth


def test_half_hidden_object_is_below_the_floor():
    """Rule 1: the default fraction floor is 0.5 (was 0.25): a can 40 % visible is never named."""
    assert Floor().min_visible_fraction == 0.5
    f = _with(_scene(), 2, visible_fraction=0.4)
    g = build_graph(f)
    assert g.node(2).attributes["below_floor"] == "below_floor_fraction" and g.node(2).phrases == []
    assert g.meta["truth_floor"]["min_visible_fraction"] == 0.5


def test_sliver_of_a_broad_object_is_below_the_floor_but_a_pen_is_not():
    """Rule 2: a 2-px strip of the book (a broad object seen edge-on) is a sliver; the same strip for a pen-thin
    box (its middle extent 7 mm) is what that object looks like, so it stays."""
    f = _scene()
    strip = np.zeros((480, 640), bool)
    strip[300:302, 200:330] = True  # 260 px, 2 px thick
    book = _with(f, 4, mask=RLE.encode(strip))
    g = build_graph(book)
    assert g.node(4).attributes["below_floor"] == "below_floor_thin", g.node(4).attributes
    assert g.meta["truth"]["below_floor_thin"] == 1
    pen = _with(book, 4, box=_box(0.0, -0.2, 0.18, 0.007, 0.007))
    assert "below_floor" not in build_graph(pen).node(4).attributes
    qa = generate_qa([f], [build_graph(f)], np.random.default_rng(1), load_recipe("recipes/default.yaml").qa)
    forged = [q for q in qa if 4 in named_objects(q)]
    assert forged
    problems = check_truth(forged[0], {book.frame_id: book}, {book.frame_id: g})
    assert any("sliver" in p for p in problems), problems


def _cut_scene():
    """The green can (3) reaches the image border: its mask gets a strip at the right edge."""
    f = _scene()
    m = f.object(3).mask.decode()
    ys = np.flatnonzero(m.any(axis=1))
    m[ys[0] : ys[0] + 6, 630:640] = True
    return _with(f, 3, mask=RLE.encode(m))


def test_cut_object_gets_no_size_question_and_no_front(cfg):
    """Rule 3: a can cut by the border is named (its place is seen) but no size relation, size value or size
    superlative of cans is asked, and its front is withheld (orientation undecided)."""
    f = _cut_scene()
    g = build_graph(f)
    a = g.node(3).attributes
    assert a["sized"] is False and a["size_check"] == "cut_by_border"
    assert a["front"] is None and a["front_check"] == "front_withheld_cut_by_border"
    assert g.node(1).attributes["front"] is not None  # the others keep theirs
    qas, truth = _many(f, g, cfg)
    assert truth.get(SIZE_CUT, 0) > 0
    assert any(3 in named_objects(q) for q in qas)  # still a referent
    for q in qas:
        if not SIZE_RELATIONS.isdisjoint(q.relations):
            assert 3 not in named_objects(q), q.question
        for word in ("tallest", "shortest", "biggest", "smallest"):
            assert f"{word} can" not in q.question and not any(f"{word} {c} can" in q.question for c in ("red", "blue"))
    assert verify_sample(Sample("s", [f], [g], qas)) == []


def test_verify_fails_a_size_question_about_a_cut_object(cfg):
    """verify's own border check: a size pair about the green can fails once the stored mask reaches the border."""
    f = _scene()
    g = build_graph(f)
    qas, _ = _many(f, g, cfg, n=6)
    sized = [q for q in qas if not SIZE_RELATIONS.isdisjoint(q.relations) and 3 in named_objects(q)]
    assert sized
    cut = _cut_scene()
    problems = check_truth(sized[0], {cut.frame_id: cut}, {cut.frame_id: g})
    assert any("border" in p for p in problems), problems


def test_half_seen_object_has_no_front():
    """Rule 3: a front needs min_front_visible_fraction (0.7): a can 60 % seen keeps its name, not its front."""
    g = build_graph(_with(_scene(), 1, visible_fraction=0.6))
    a = g.node(1).attributes
    assert "below_floor" not in a and a["front"] is None and a["front_check"] == "front_withheld_hidden"
    assert g.meta["truth"]["front_withheld_hidden"] == 1


def _clearance_px(frame, region, point) -> float:
    W, H = frame.camera.width, frame.camera.height
    u, v = int(point[0] * W), int(point[1] * H)
    d = float(min(u, v, W - 1 - u, H - 1 - v))
    for o in frame.objects:
        ys, xs = np.nonzero(o.mask.decode())
        d = min(d, float(np.hypot(xs - u, ys - v).min()))
    return d


def test_free_space_points_keep_clear_of_objects_and_border():
    """Rule 4: every free-space answer point keeps min_point_clearance_px (20 px at 640x480) from every mask and
    the image border; before, the farthest-inside sample of a region could touch an object in the image."""
    need = 20.0  # min_point_clearance_px at 640x480
    checked = 0
    for seed in range(4):
        f = toy_frame(np.random.default_rng(seed), n_objects=7, width=640, height=480)
        g = build_graph(f)
        for r in g.free_space:
            assert _clearance_px(f, r, r.point) >= need, (seed, r.kind, r.anchors, r.point)
            checked += 1
    assert checked > 20
    assert Floor().min_point_clearance_px * px_scale(640, 480) == need


def test_verify_fails_a_free_space_point_next_to_an_object(cfg):
    f = _scene()
    g = build_graph(f)
    qas, _ = _many(f, g, cfg, n=8)
    placed = [q for q in qas if "free_space" in q.relations and isinstance(q.answer_struct.get("region"), dict)]
    assert placed
    q = placed[0]
    assert check_truth(q, {f.frame_id: f}, {f.frame_id: g}) == []
    m = f.object(1).mask.decode()  # move the red can's mask next to the point
    u, v = int(q.answer_struct["points"][0][0] * 640), int(q.answer_struct["points"][0][1] * 480)
    m[v, max(0, u - 5) : u - 3] = True
    moved = _with(f, 1, mask=RLE.encode(m))
    problems = check_truth(q, {f.frame_id: moved}, {f.frame_id: g})
    assert any("px of object 1" in p for p in problems), problems
