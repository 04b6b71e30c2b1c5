"""Preview overlays and gallery: drawn where the geometry says, seeded, deterministic, self-contained HTML."""

from __future__ import annotations

import json
import re

import numpy as np
import pytest

from refspatial_gen.core.geometry import Box3D
from refspatial_gen.core.mask import answer_pixel, denormalise_point, normalise_point
from refspatial_gen.core.model import FreeSpaceRegion, KeyStep, Node, QAPair, Sample, SceneGraph
from refspatial_gen.run import draw
from refspatial_gen.run.preview import (
    answer_points,
    point_checks,
    render_preview,
    reservoir,
    reservoir_pick,
    write_gallery,
)
from refspatial_gen.sources.toy import toy_frame


def _free_square(frame, half: float = 0.06) -> FreeSpaceRegion:
    """A square on the table top far from every object, with its projected centre as the answer point."""
    table = frame.surfaces[0]
    z = table.top_z
    best, best_d = None, -1.0
    for x in np.linspace(-0.45, 0.45, 19):
        for y in np.linspace(-0.28, 0.28, 12):
            d = min(float(np.linalg.norm(o.box.center[:2] - [x, y])) for o in frame.objects)
            uv, _ = frame.camera.project(np.array([[x, y, z]]))
            inside = 0 <= uv[0, 0] < frame.camera.width and 0 <= uv[0, 1] < frame.camera.height
            if inside and d > best_d:
                best, best_d = (float(x), float(y)), d
    x, y = best
    poly = [(x - half, y - half), (x + half, y - half), (x + half, y + half), (x - half, y + half)]
    uv, _ = frame.camera.project(np.array([[x, y, z]]))
    p = normalise_point(float(np.floor(uv[0, 0])), float(np.floor(uv[0, 1])), frame.camera.width, frame.camera.height)
    return FreeSpaceRegion("table", "empty", (), poly, z, (2 * half) ** 2, (x, y, z), p, "open area")


def _obj_point(frame, oid: int) -> tuple[float, float]:
    o = frame.object(oid)
    x, y = answer_pixel(o.mask.decode())
    return normalise_point(x, y, frame.camera.width, frame.camera.height)


def make_preview_sample(seed: int = 7, sample_id: str = "s0", frame_id: str = "toy:000007") -> Sample:
    """A toy frame with a graph (nodes + one free-space region) and hand-made QA pairs of every answer kind."""
    frame = toy_frame(np.random.default_rng(seed), 6, 320, 240, frame_id=frame_id)
    W, H = frame.camera.width, frame.camera.height
    objs = sorted(frame.objects, key=lambda o: o.id)
    a, b = objs[0], objs[1]
    pa, pb = _obj_point(frame, a.id), _obj_point(frame, b.id)
    region = _free_square(frame)
    nodes = [Node(o.id, o.category, {"color": o.attributes["color"]}, [f"the {o.attributes['color']} {o.category}"],
                  _obj_point(frame, o.id), "table") for o in objs]
    graph = SceneGraph(frame.frame_id, nodes, [], [region], {"scale": "tabletop"})
    ca, cb = f"the {a.attributes['color']} {a.category}", f"the {b.attributes['color']} {b.category}"
    dist = float(np.linalg.norm(a.box.center - b.box.center))
    qa = [
        QAPair("q-locate", "locate", "locate_simple", f"Point to {ca}. Answer with [(x, y)] in 0-1.",
               f"[({pa[0]:.3f}, {pa[1]:.3f})]", {"kind": "points", "points": [list(pa)]}, [], 1, [frame.frame_id],
               (W, H), checks=["unique_phrase", "point_in_mask"], targets=[a.id]),
        QAPair("q-place", "placement", "place_free", "Point to a free spot on the table where a cup could go.",
               f"[({region.point[0]:.3f}, {region.point[1]:.3f})]",
               {"kind": "region", "points": [list(region.point)], "surface_id": "table"}, ["free_space"], 1,
               [frame.frame_id], (W, H), checks=["point_in_region"]),
        QAPair("q-choice", "choice", "yn_left", f"Is {ca} left of {cb}? (A) yes (B) no", "(A)",
               {"kind": "choice", "options": ["yes", "no"], "correct": 0}, ["left_of"], 2, [frame.frame_id], (W, H),
               trace=f"<think>[Position] {ca}: ({pa[0]:.3f}, {pa[1]:.3f})\n[Position] {cb}: ({pb[0]:.3f}, {pb[1]:.3f})"
                     "</think><answer>(A)</answer>",
               key_steps=[KeyStep("Position", ca, list(pa)), KeyStep("Position", cb, list(pb))],
               targets=[a.id, b.id]),
        QAPair("q-dist", "quantitative", "distance", f"How far is {ca} from {cb}?", f"{dist:.2f} meters",
               {"kind": "number", "value": round(dist, 3), "unit": "m"}, ["distance"], 2, [frame.frame_id], (W, H),
               trace=f"<think>[Position] {ca}: ({pa[0]:.3f}, {pa[1]:.3f})\n[Size] {cb}: {b.box.height:.3f}</think>"
                     f"<answer>{dist:.2f} meters</answer>",
               key_steps=[KeyStep("Position", ca, list(pa)), KeyStep("Size", cb, [b.box.height])],
               targets=[a.id, b.id]),
    ]
    return Sample(sample_id, [frame], [graph], qa, unit_key=frame_id, meta={"source": "toy"})


def _stream(k: int = 3):
    for i in range(k):
        yield f"shard-{i:05d}.mcap", make_preview_sample(seed=7 + i, sample_id=f"s{i}", frame_id=f"toy:{i:06d}")


# ------------------------------------------------------------------------------------------------ drawing
def test_point_marker_lands_on_the_answer_pixel():
    rgb = np.zeros((40, 50, 3), np.uint8)
    ov = draw.Overlay.from_rgb(rgb, display_width=100)  # scale 2
    assert ov.scale == 2.0
    x, y = normalise_point(13, 29, 50, 40)
    ov.point(x * 50, y * 40, draw.ANSWER, radius=3)
    out = ov.rgb()
    cy, cx = int(round(y * 40 * 2)), int(round(x * 50 * 2))
    assert tuple(out[cy, cx]) == draw.ANSWER  # centre of the (13, 29) pixel, scaled
    red = np.all(out == draw.ANSWER, axis=-1)
    ys, xs = np.nonzero(red)
    assert abs(xs.mean() - (13.5 * 2)) < 1.0 and abs(ys.mean() - (29.5 * 2)) < 1.0


def test_projected_box_edges_match_camera_projection(toy_frame):
    o = toy_frame.objects[0]
    segs = draw.project_box_edges(toy_frame.camera, o.box)
    assert len(segs) == 12
    uv, _ = toy_frame.camera.project(o.box.corners())
    ends = {tuple(np.round(p, 6)) for s in segs for p in s}
    assert ends == {tuple(np.round(p, 6)) for p in uv}
    # every edge joins corners that differ along exactly one box axis
    assert all(bin(i ^ j).count("1") == 1 for i, j in draw.BOX_EDGES)
    # the projected box contains the object's 2D box (the visible part of a box lies inside its outline)
    x0, y0, x1, y1 = o.bbox2d
    assert uv[:, 0].min() <= x0 + 1 and uv[:, 0].max() >= x1 - 1
    assert uv[:, 1].min() <= y0 + 1 and uv[:, 1].max() >= y1 - 1


def test_box_behind_camera_is_left_out(toy_frame):
    cam = toy_frame.camera
    behind = cam.cam_to_world(np.array([[0.0, 0.0, -1.0]]))[0]
    assert draw.project_box_edges(cam, Box3D(behind, [0.1, 0.1, 0.1], np.eye(3))) == []
    assert draw.project_polygon(cam, [(behind[0], behind[1]), (behind[0] + 0.1, behind[1]),
                                      (behind[0], behind[1] + 0.1)], behind[2]) is None


def test_plane_visibility_hides_the_table_behind_objects(toy_frame):
    cam, depth = toy_frame.camera, toy_frame.depth
    top = toy_frame.surfaces[0].top_z
    vis = draw.plane_visibility(cam, depth, top)
    vs, us = np.nonzero(depth > 0)
    world = cam.cam_to_world(cam.backproject(us + 0.5, vs + 0.5, depth[vs, us]))
    on_top = np.abs(world[:, 2] - top) < 1e-3  # pixels whose surface is the table top itself
    assert on_top.sum() > 1000 and vis[vs[on_top], us[on_top]].mean() > 0.99
    above = world[:, 2] > top + 0.03  # object surfaces 3 cm or more above the table hide it
    assert above.sum() > 1000 and vis[vs[above], us[above]].mean() < 0.01
    objects = np.zeros_like(vis)
    for o in toy_frame.objects:
        objects |= o.mask.decode()
    assert vis[objects].mean() < 0.2  # thin objects (trays, books) within the depth tolerance excepted
    assert draw.plane_visibility(cam, np.zeros_like(depth), top).sum() > 0.5 * depth.size  # unknown depth: seen


def test_wrap_respects_width_and_keeps_every_word():
    f = draw.font(15)
    text = "Point to the red box that is left of the blue can and behind the tray " * 4
    lines = draw.wrap(text.strip() + "\n" + "x" * 300, f, 300)
    assert all(f.getlength(line) <= 300 for line in lines)
    words = [ln for ln in lines if not ln.startswith("x")]
    assert " ".join(words).split() == text.split() and len(words) > 3  # wrapped, nothing lost or reordered
    assert len(lines) - len(words) > 1  # the long word was broken over several lines
    assert "".join(lines).replace(" ", "") == (text + "x" * 300).replace(" ", "")


# ------------------------------------------------------------------------------------------------ render
def test_render_preview_draws_answer_targets_and_region():
    s = make_preview_sample()
    f = s.frames[0]
    scale = 720 / f.camera.width
    base = draw.Overlay.from_rgb(f.rgb).rgb()
    img = render_preview(s, 0)  # locate: one answer point on target a
    assert img.dtype == np.uint8 and img.shape[1] >= 720 and img.shape[0] > base.shape[0] + 100
    top = img[: base.shape[0]]
    (x, y), = answer_points(s.qa[0].answer_struct)
    u, v = int(round(x * f.camera.width * scale)), int(round(y * f.camera.height * scale))
    assert tuple(top[v, u]) == draw.ANSWER
    # the target's 2D box outline is drawn (yellow pixels on its top edge)
    x0, y0, x1, _ = s.frames[0].object(s.qa[0].targets[0]).bbox2d
    edge = top[int(y0 * scale) : int(y0 * scale) + 2, int(x0 * scale) + 4 : int(x1 * scale) - 4]
    assert np.mean(np.all(edge == draw.TARGET_2D, axis=-1)) > 0.5
    # a text panel exists under the image (dark background, light text)
    panel = img[base.shape[0] :]
    assert (panel.max(axis=-1) > 200).sum() > 500

    place = render_preview(s, 1)[: base.shape[0]]  # placement: answer region filled orange-ish
    reg = s.graphs[0].free_space[0]
    uv = draw.project_polygon(f.camera, reg.polygon_xy, reg.z) * scale
    c = uv.mean(axis=0)
    px = place[int(c[1]) + 12, int(c[0])].astype(int)  # inside the polygon, off the marker
    assert px[0] > base[int(c[1]) + 12, int(c[0]), 0] and px[2] < 200


def test_point_checks_pass_for_correct_points_and_fail_for_wrong_ones():
    s = make_preview_sample()
    checks = point_checks(s, s.qa[0])
    assert len(checks) == 1 and checks[0][1] and "in target mask" in checks[0][0]
    assert point_checks(s, s.qa[1])[0][1]  # placement point inside its region
    # move the locate answer onto the background: the check must fail and the panel says so
    f = s.frames[0]
    mask = np.zeros((f.camera.height, f.camera.width), bool)
    for o in f.objects:
        mask |= o.mask.decode()
    ys, xs = np.nonzero(~mask)
    s.qa[0].answer_struct = {"kind": "points", "points": [list(normalise_point(xs[0], ys[0], 320, 240))]}
    text, ok = point_checks(s, s.qa[0])[0]
    assert not ok and "NO" in text
    px, py = denormalise_point(*answer_points(s.qa[0].answer_struct)[0], 320, 240)
    assert not mask[py, px]


def test_render_preview_is_deterministic_and_handles_every_kind():
    s1, s2 = make_preview_sample(), make_preview_sample()
    for i in range(len(s1.qa)):
        a, b = render_preview(s1, i), render_preview(s2, i)
        assert a.shape == b.shape and np.array_equal(a, b)
    assert not np.array_equal(render_preview(s1, 0), render_preview(s1, 2))


def test_render_preview_unknown_frame_is_an_error():
    s = make_preview_sample()
    s.qa[0].frame_ids = ["nope"]
    with pytest.raises(KeyError, match="nope"):
        render_preview(s, 0)


# ------------------------------------------------------------------------------------------------ gallery
def test_reservoir_pick_is_seeded_and_bounded():
    stream = list(_stream(3))
    picks = reservoir_pick(stream, 5, seed=1)
    again = reservoir_pick(iter(stream), 5, seed=1)
    assert [p.order for p, _ in picks] == [p.order for p, _ in again]
    assert len(picks) == 5 and len({p.order for p, _ in picks}) == 5
    assert [p.order for p, _ in picks] == sorted(p.order for p, _ in picks)
    for p, s in picks:
        assert s.sample_id == p.sample_id and s.qa[p.qa_index].qa_id == p.qa_id
        assert p.source == f"shard-{int(p.sample_id[1:]):05d}.mcap"
    assert len(reservoir_pick(stream[:1], 50, seed=0)) == 4  # fewer QA pairs than asked: all of them
    assert reservoir_pick(stream, 0, seed=0) == []


def test_reservoir_is_uniform_and_holds_at_most_n():
    counts = np.zeros(12)
    for seed in range(400):
        picked = reservoir(range(12), 5, seed)
        assert [t for t, _ in picked] == [v for _, v in picked] == sorted(v for _, v in picked)
        for t, _ in picked:
            counts[t] += 1
    expected = 400 * 5 / 12  # every item equally likely, late ones too
    assert counts.min() > 0.8 * expected and counts.max() < 1.2 * expected

    class Watch:
        alive = 0

        def __init__(self):
            Watch.alive += 1

        def __del__(self):
            Watch.alive -= 1

    peak = 0

    def gen():
        nonlocal peak
        for _ in range(300):
            yield Watch()
            peak = max(peak, Watch.alive)

    assert len(reservoir(gen(), 4, seed=0)) == 4
    assert peak <= 4 + 2  # the n kept, the new candidate and at most one in flight


def test_write_gallery_files_links_and_escaping(tmp_path):
    stream = list(_stream(2))
    stream[0][1].qa[2].question = "Is <b>this</b> & that left? (A) yes (B) no"
    index = write_gallery(stream, tmp_path / "g", n=5, seed=3)
    page = index.read_text(encoding="utf-8")
    listing = json.loads((tmp_path / "g" / "preview.json").read_text())
    files = [p["file"] for p in listing["picked"]]
    assert len(files) == 5 and all((tmp_path / "g" / f).is_file() for f in files)
    links = re.findall(r'src="([^"]+)"', page)
    assert links == files  # relative links, one per picked QA pair
    assert "<b>this</b>" not in page
    if any(p["qa_id"] == "q-choice" and p["sample_id"] == "s0" for p in listing["picked"]):
        assert "&lt;b&gt;this&lt;/b&gt; &amp; that" in page
    assert all(c["ok"] for p in listing["picked"] for c in p["checks"])
    # same inputs -> same bytes
    index2 = write_gallery(stream, tmp_path / "g2", n=5, seed=3)
    for f in files + ["index.html", "preview.json"]:
        assert (tmp_path / "g" / f).read_bytes() == (index2.parent / f).read_bytes()


def _preview_cli(argv):
    import argparse

    from refspatial_gen.cli import preview as preview_commands

    parser = argparse.ArgumentParser(prog="refspatial-gen")
    preview_commands.register(parser.add_subparsers(dest="command", required=True))
    args = parser.parse_args(argv)
    return args, args.func(args)


def test_preview_command_is_registered_and_reports_missing_shards(tmp_path, capsys):
    from refspatial_gen import cli

    assert "refspatial_gen.cli.preview" in cli.COMMAND_MODULES
    args, rc = _preview_cli(["preview", str(tmp_path), "--out", str(tmp_path / "o"), "--n", "3", "--seed", "5"])
    assert (args.n, args.seed) == (3, 5) and rc == 1
    assert "no .mcap shards" in capsys.readouterr().err
    assert not (tmp_path / "o").exists()


def test_preview_command_reads_real_shards(tmp_path):
    reader = pytest.importorskip("refspatial_gen.shards.reader", reason="shards package not available yet")
    writer_mod = pytest.importorskip("refspatial_gen.shards.writer", reason="shard writer not available yet")
    from refspatial_gen.run.preview import iter_shard_samples, pick_from_shards

    stream = list(_stream(4))
    for k in range(2):  # two shards of two samples, in a nested folder
        shard = tmp_path / "run" / "shards" / f"shard-{k:05d}.mcap"
        shard.parent.mkdir(parents=True, exist_ok=True)
        w = writer_mod.ShardWriter(shard)
        for _, s in stream[2 * k : 2 * k + 2]:
            w.write(s)
        w.finish()
        assert sum(1 for _ in reader.read_samples(shard)) == 2
    (tmp_path / "run" / "shards" / "shard-00009.mcap.partial").write_bytes(b"junk")  # unfinished: ignored
    # the metadata-only sampling pass picks exactly what sampling the decoded stream picks
    for seed in (0, 1, 2):
        fast = pick_from_shards(tmp_path / "run", 5, seed)
        full = reservoir_pick(iter_shard_samples(tmp_path / "run"), 5, seed)
        assert [p for p, _ in fast] == [p for p, _ in full]
        assert [s.sample_id for _, s in fast] == [s.sample_id for _, s in full]
    assert _preview_cli(["preview", str(tmp_path / "run"), "--out", str(tmp_path / "o"), "--n", "5"])[1] == 0
    listing = json.loads((tmp_path / "o" / "preview.json").read_text())
    assert len(listing["picked"]) == 5 and len(list((tmp_path / "o").glob("qa_*.png"))) == 5
    assert {p["source"] for p in listing["picked"]} <= {"shards/shard-00000.mcap", "shards/shard-00001.mcap"}
    # answers still land on their targets after the shard round trip (masks are stored losslessly)
    assert all(c["ok"] for p in listing["picked"] for c in p["checks"])
    # fewer pairs on a re-run: stale images are removed
    assert _preview_cli(["preview", str(tmp_path / "run"), "--out", str(tmp_path / "o"), "--n", "2"])[1] == 0
    assert len(list((tmp_path / "o").glob("qa_*.png"))) == 2


def test_multiview_sample_shows_frames_side_by_side_with_points_on_the_answer_frame():
    a = make_preview_sample(seed=7, frame_id="view0")
    b = make_preview_sample(seed=8, frame_id="view1")
    qa = b.qa[0]  # points at an object of view1
    qa.frame_ids = ["view0", "view1"]
    qa.answer_struct = {**qa.answer_struct, "frame_id": "view1"}
    s = Sample("mv", a.frames + b.frames, a.graphs + b.graphs, [qa])
    img = render_preview(s, 0)
    single = render_preview(b, 0)
    assert img.shape[1] >= 2 * 720 and single.shape[1] == 720
    half = img[:585]
    left, right = half[:, :720], half[:, 726:726 + 720]
    assert np.all(left == draw.ANSWER, axis=-1).sum() == 0  # no answer marker on the question-only view
    assert np.all(right == draw.ANSWER, axis=-1).sum() > 20
    assert point_checks(s, qa)[0][1]


def test_two_view_question_is_drawn_in_the_order_the_question_names_its_images():
    """"The first image" is qa.frame_ids[0]; the preview drew the sample's stored order, so a question on
    (view1, view0) showed view0 first and looked wrong to a reviewer although the data was right."""
    a = make_preview_sample(seed=7, frame_id="view0")
    b = make_preview_sample(seed=8, frame_id="view1")
    qa = b.qa[0]
    qa.frame_ids = ["view1", "view0"]  # the question's first image is the sample's second frame
    qa.answer_struct = {**qa.answer_struct, "frame_id": "view1"}
    s = Sample("mv", a.frames + b.frames, a.graphs + b.graphs, [qa])
    img = render_preview(s, 0)[:585]
    left, right = img[:, :720], img[:, 726:726 + 720]
    assert np.all(left == draw.ANSWER, axis=-1).sum() > 20  # view1 (the answer's frame) is image 1, on the left
    assert np.all(right == draw.ANSWER, axis=-1).sum() == 0
    from refspatial_gen.run.preview import question_frames

    assert [f.frame_id for f in question_frames(s, qa)] == ["view1", "view0"]
