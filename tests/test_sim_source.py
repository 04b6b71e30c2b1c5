"""The simulated source: catalog, consistency of frames (masks, depth, boxes), determinism, settling."""

from __future__ import annotations

import os
from pathlib import Path

import numpy as np
import pytest

os.environ.setdefault("MUJOCO_GL", "egl")

from refspatial_gen.assets import build_geometry, load_catalog  # noqa: E402
from refspatial_gen.core.errors import DropUnit, RecipeError  # noqa: E402

SMALL = {"width": 320, "height": 240, "views": 2, "layouts": {"tabletop": 1.0}, "min_objects": 5, "max_objects": 8}


@pytest.fixture(scope="module")
def scene():
    from refspatial_gen.sources.sim import generate

    return generate("sim:000003", np.random.default_rng(3), SMALL, keep_scene=True)


def test_catalog_has_40_categories_with_sizes_and_fronts():
    cat = load_catalog()
    procedural = [c for c in cat.categories.values() if c.builder != "external"]
    assert len(procedural) >= 40
    assert len(cat.names("room")) >= 6
    fronts = {c.name: c.front_phrase for c in procedural if c.front is not None}
    assert fronts["mug"] == "the handle side" and fronts["laptop"] == "the screen side" and fronts["teapot"] == "the spout"
    rng = np.random.default_rng(0)
    for c in procedural:
        d = c.sample_dims(rng)
        lo, hi = build_geometry(c, d, rng).bounds()
        size = hi - lo
        assert abs(lo[2]) < 0.003, c.name  # origin at the bottom
        assert 0.005 < size.max() < 2.0, (c.name, size)
        for k, (a, b) in c.dims.items():
            assert a <= d[k] <= b


def test_catalog_error_points_at_line(tmp_path: Path):
    p = tmp_path / "cat.yaml"
    p.write_text("colors:\n  red: [1, 0, 0]\nmaterials:\n  plastic: {}\ncategories:\n  thing:\n    builder: box\n"
                 "    dims: {x: [0.1, 0.2], y: [0.1, 0.1], z: [0.1, 0.1]}\n    colors: [mauve]\n")
    with pytest.raises(RecipeError) as e:
        load_catalog(str(p))
    assert e.value.line == 9 and "mauve" in e.value.message


def test_frames_are_consistent(scene):
    frames, desc, sim = scene
    assert len(frames) == 2 and frames[0].scene_id == frames[1].scene_id == "sim:000003"
    assert [f.frame_id for f in frames] == ["sim:000003/v0", "sim:000003/v1"]
    for f in frames:
        f.validate()
        assert f.source == "sim" and f.rgb.std() > 10  # a real render, not blank
        cam = f.camera
        pitch = np.degrees(np.arcsin(-cam.world_from_cam[2, 2]))
        table = next(s for s in f.surfaces if s.kind == "table")
        assert table.name == "the table"
        assert 30 - 1e-6 <= pitch <= 60 + 1e-6
        assert 0.3 - 1e-6 <= cam.position[2] - table.top_z <= 0.8 + 1e-6
        ids = [o.id for o in f.objects]
        assert len(ids) >= 2 and all(i > 0 for i in ids)
        for o in f.objects:
            m = o.mask.decode()
            assert m.any()
            ys, xs = np.nonzero(m)
            assert o.bbox2d == (xs.min(), ys.min(), xs.max() + 1, ys.max() + 1)
            assert 0 < o.visible_fraction <= 1
            assert np.allclose(o.box.rotation[2], [0, 0, 1])  # gravity-aligned
            # back-projected depth of the mask lies in the object's box (depth is metric z-depth)
            z = f.depth[ys, xs]
            assert (z > 0).all()
            pts = cam.cam_to_world(cam.backproject(xs + 0.5, ys + 0.5, z))
            inside = o.box.contains(pts, pad=0.002).mean()
            assert inside > 0.999, (o.category, inside)
            if o.front is not None:
                assert abs(np.linalg.norm(o.front) - 1) < 1e-6 and o.front_phrase
            assert set(o.attributes) == {"color", "material"}


def test_depth_matches_table_plane(scene):
    frames, _, _ = scene
    f = frames[0]
    seg_none = np.ones(f.depth.shape, bool)
    for o in f.objects:
        seg_none &= ~o.mask.decode()
    vs, us = np.nonzero(seg_none & (f.depth > 0))
    # pixel (u, v) covers [u, u+1) x [v, v+1): its centre is (u + 0.5, v + 0.5) with cx = W / 2
    pts = f.camera.cam_to_world(f.camera.backproject(us + 0.5, vs + 0.5, f.depth[vs, us]))
    table = next(s for s in f.surfaces if s.kind == "table")
    local = np.abs(table.box.to_local(pts))
    on_top = (local[:, 0] < table.box.size[0] / 2 - 0.02) & (local[:, 1] < table.box.size[1] / 2 - 0.02) & (local[:, 2] < 0.05)
    # table-top pixels (away from its side faces) are exactly at the top face height
    assert on_top.sum() > 100
    assert np.abs(pts[on_top][:, 2] - table.top_z).max() < 5e-4  # exact metric z-depth, no anti-aliasing


def test_same_key_and_seed_is_identical():
    from refspatial_gen.sources.sim import generate

    cfg = {**SMALL, "views": 1}
    a = generate("sim:000011", np.random.default_rng(11), cfg)
    b = generate("sim:000011", np.random.default_rng(11), cfg)
    assert np.array_equal(a[0].rgb, b[0].rgb) and np.array_equal(a[0].depth, b[0].depth)
    assert [o.to_json() for o in a[0].objects] == [o.to_json() for o in b[0].objects]
    c = generate("sim:000011", np.random.default_rng(12), cfg)
    assert not np.array_equal(a[0].rgb, c[0].rgb)


def test_unsettled_scene_is_dropped_with_reason():
    from refspatial_gen.sources.sim import source
    from refspatial_gen.sources.sim.rooms import tabletop_layout
    from refspatial_gen.sources.sim.physics import build_model, settle

    cat = load_catalog()
    cfg = source._cfg({**SMALL, "settle_max_steps": 200})
    cfg["_colors"] = cat.colors
    desc = tabletop_layout(cat, np.random.default_rng(5), cfg)
    desc.objects[0].pos = desc.objects[0].pos + np.array([0, 0, 2.0])  # planted: still falling at the step cap
    with pytest.raises(DropUnit) as e:
        settle(build_model(desc, cat.materials, cfg, 1), cfg)
    assert e.value.reason == "physics_not_settled"
    desc = tabletop_layout(cat, np.random.default_rng(5), cfg)  # the same scene unplanted settles
    info = settle(build_model(desc, cat.materials, cfg, 1), {**cfg, "settle_max_steps": 3000})
    assert info["steps"] < 3000 and info["max_lin_vel"] < cfg["settle_lin_vel"]


def test_layout_has_no_interpenetration():
    from refspatial_gen.core.geometry import inside_fraction
    from refspatial_gen.sources.sim import source
    from refspatial_gen.sources.sim.frames import scene_boxes
    from refspatial_gen.sources.sim.layout import CLEARANCE
    from refspatial_gen.sources.sim.rooms import room_layout
    from refspatial_gen.sources.sim.physics import build_model, settle

    cat = load_catalog()
    cfg = source._cfg(SMALL)
    cfg["_colors"] = cat.colors
    desc = room_layout(cat, np.random.default_rng(21), cfg)
    for s in desc.surfaces:
        for i, a in enumerate(s.fps):
            for b in s.fps[i + 1:]:
                assert a.distance(b) >= CLEARANCE - 1e-9 or s.id == "floor"
    sim = build_model(desc, cat.materials, cfg, 1)
    settle(sim, cfg)  # raises DropUnit("interpenetration") on deep contacts
    boxes = [b for b, _ in scene_boxes(sim, desc)]
    for i, a in enumerate(boxes):
        for j, b in enumerate(boxes):
            nested = desc.objects[i].support in (f"in:{desc.objects[j].key}",) or desc.objects[j].support == f"in:{desc.objects[i].key}"
            if i < j and not nested:
                assert min(inside_fraction(a, b), inside_fraction(b, a)) < 0.3, (desc.objects[i].category.name, desc.objects[j].category.name)


def test_registered_source_and_unit_keys():
    from refspatial_gen.sources import get_source

    src = get_source("sim")
    assert src.name == "sim" and "views" in src.CONFIG_FIELDS
    assert src.unit_keys({}, 3, None) == ["sim:000000", "sim:000001", "sim:000002"]


def test_usd_export_and_assets_list(tmp_path: Path, capsys):
    from pxr import Usd, UsdGeom

    from refspatial_gen.cli import main

    assert main(["assets", "list", "--json"]) == 0
    import json

    rows = json.loads(capsys.readouterr().out)["categories"]
    assert len(rows) >= 40 and any(r["front_phrase"] == "the handle side" for r in rows)
    out = tmp_path / "scene.usda"
    assert main(["sim", "usd", "--unit", "sim:000003", "--seed", "7", "--out", str(out), "--views", "1"]) == 0
    stage = Usd.Stage.Open(str(out))
    objs = [p for p in stage.Traverse() if p.HasAttribute("refspatial:category")]
    assert len(objs) >= 3
    cache = UsdGeom.BBoxCache(Usd.TimeCode.Default(), [UsdGeom.Tokens.default_])
    for p in objs:
        size = cache.ComputeWorldBound(p).ComputeAlignedRange().GetSize()
        assert 0.003 < max(size) < 2.0
    assert any(p.IsA(UsdGeom.Camera) for p in stage.Traverse())
