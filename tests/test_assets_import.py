"""`assets import`: every format with its metadata, no hand-written entries; set-front and the sheet."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest
import trimesh
from PIL import Image

from refspatial_gen.assets import build_geometry, load_catalog
from refspatial_gen.assets.importer import import_assets, infer_scale

SLAB_OBJ = """mtllib slab.mtl
usemtl tex
v -5 -3 0
v 5 -3 0
v 5 3 0
v -5 3 0
v -5 -3 2
v 5 -3 2
v 5 3 2
v -5 3 2
vt 0 0
vt 1 0
vt 1 1
vt 0 1
f 5/1 6/2 7/3
f 5/1 7/3 8/4
f 1/1 3/3 2/2
f 1/1 4/4 3/3
f 1/1 2/2 6/2
f 1/1 6/2 5/1
f 2/2 3/3 7/3
f 2/2 7/3 6/2
f 3/3 4/4 8/4
f 3/3 8/4 7/3
f 4/4 1/1 5/1
f 4/4 5/1 8/4
"""


def _library(root: Path) -> Path:
    lib = root / "lib"
    (lib / "slab").mkdir(parents=True)
    (lib / "slab" / "slab.obj").write_text(SLAB_OBJ)  # centimetres, z up, textured
    (lib / "slab" / "slab.mtl").write_text("newmtl tex\nKd 1 1 1\nmap_Kd slab.png\n")
    img = np.zeros((64, 64, 3), np.uint8)
    img[:, :32] = (200, 30, 30)
    img[:, 32:] = (240, 220, 30)
    Image.fromarray(img).save(lib / "slab" / "slab.png")
    tall = trimesh.creation.box(extents=[0.05, 0.2, 0.05])  # glTF: y up, metres
    tall.visual = trimesh.visual.ColorVisuals(tall, face_colors=[30, 60, 200, 255])
    (lib / "bottle.glb").write_bytes(trimesh.Scene(tall).export(file_type="glb"))
    trimesh.creation.box(extents=[100, 60, 40]).export(lib / "brick.stl")  # millimetres
    (lib / "brick.json").write_text(json.dumps({"category": "brick", "front": "+y", "front_phrase": "the logo side",
                                                "size": 0.1, "colors": ["orange"]}))
    from pxr import Gf, Usd, UsdGeom, Vt

    stage = Usd.Stage.CreateNew(str(lib / "cube.usda"))
    UsdGeom.SetStageUpAxis(stage, UsdGeom.Tokens.y)
    UsdGeom.SetStageMetersPerUnit(stage, 0.01)
    cube = trimesh.creation.box(extents=[8, 8, 8])
    m = UsdGeom.Mesh.Define(stage, "/cube")
    m.CreatePointsAttr(Vt.Vec3fArray([Gf.Vec3f(*map(float, v)) for v in cube.vertices]))
    m.CreateFaceVertexCountsAttr(Vt.IntArray([3] * len(cube.faces)))
    m.CreateFaceVertexIndicesAttr(Vt.IntArray([int(i) for i in cube.faces.ravel()]))
    m.CreateDisplayColorAttr(Vt.Vec3fArray([Gf.Vec3f(0.1, 0.6, 0.2)]))
    stage.GetRootLayer().Save()
    return lib


def test_import_reads_every_format_and_its_metadata(tmp_path):
    lib = _library(tmp_path)
    out = tmp_path / "cats" / "mine.yaml"
    rows = import_assets([lib], out, cache=tmp_path / "cache", collision="hull")
    assert len(rows) == 4
    cat = load_catalog(str(out))
    assert "mug" in cat.categories  # extends the built-in catalog
    by_label = {c.label: c for c in cat.categories.values() if c.builder == "external"}
    assert set(by_label) == {"slab", "bottle", "brick", "cube"}
    size = {k: np.ptp(build_geometry(c, {}, None).hull_points(), axis=0) for k, c in by_label.items()}
    assert np.allclose(size["slab"], [0.10, 0.06, 0.02], atol=1e-6)  # centimetres recognised from the size range
    assert np.allclose(size["bottle"], [0.05, 0.05, 0.2], atol=1e-6)  # glTF y-up turned to z-up
    assert np.allclose(size["brick"], [0.1, 0.06, 0.04], atol=1e-6)  # scale from the annotation's real size
    assert np.allclose(size["cube"], [0.08, 0.08, 0.08], atol=1e-6)  # USD metersPerUnit
    brick = by_label["brick"]
    assert brick.front == (0.0, 1.0, 0.0) and brick.front_phrase == "the logo side" and brick.colors == ("orange",)
    slab = build_geometry(by_label["slab"], {}, None)
    tex = [p for p in slab.parts if p.texture_img is not None]
    assert tex and tex[0].uv is not None  # the MTL's texture kept with its UVs
    assert set(by_label["slab"].colors) == {"red", "yellow"}  # colour words from the texture
    assert by_label["cube"].colors[0] == "green" and by_label["bottle"].colors[0] == "blue"
    text = "".join(ln for ln in out.read_text().splitlines(keepends=True) if not ln.startswith("#"))
    assert str(tmp_path) not in text and "../lib/" in text  # paths relative to the catalog file


def test_scale_inference_picks_units_from_the_category_range():
    assert infer_scale(95.0, (0.08, 0.12)) == 0.001
    assert infer_scale(9.5, (0.08, 0.12)) == 0.01
    assert infer_scale(0.095, (0.08, 0.12)) == 1.0


def test_coacd_collision_is_cached_by_mesh_hash(tmp_path):
    import time

    lib = tmp_path / "lib"
    lib.mkdir()
    a = trimesh.creation.box(extents=[0.12, 0.03, 0.03])
    b = trimesh.creation.box(extents=[0.03, 0.12, 0.03])
    b.apply_translation([0.045, 0.045, 0])
    trimesh.boolean.union([a, b]).export(lib / "corner.stl")  # an L: its hull would fill the inner corner
    t0 = time.perf_counter()
    import_assets([lib], tmp_path / "c.yaml", cache=tmp_path / "cache", collision="auto")
    first = time.perf_counter() - t0
    parts = sorted((tmp_path / "cache" / "collision").glob("*/part*.stl"))
    assert len(parts) >= 2
    t0 = time.perf_counter()
    import_assets([lib], tmp_path / "c2.yaml", cache=tmp_path / "cache", collision="auto")
    assert time.perf_counter() - t0 < first / 2  # the cache answered
    geo = build_geometry(load_catalog(str(tmp_path / "c2.yaml")).categories["lib corner"], {}, None)
    assert sum(1 for p in geo.parts if p.collide) == len(parts)


def test_set_front_edits_the_defining_file_and_the_sheet_draws_it(tmp_path):
    from refspatial_gen.assets.edit import set_front
    from refspatial_gen.sources.sim.sheet import asset_sheet

    lib = _library(tmp_path)
    out = tmp_path / "mine.yaml"
    import_assets([lib], out, cache=tmp_path / "cache", collision="hull")
    before = out.read_text()
    with pytest.raises(ValueError):  # "bottle" is also a built-in category: never edited through an include
        set_front(load_catalog(str(out)), "bottle", "-x", "the cap side")
    file, front = set_front(load_catalog(str(out)), "lib bottle", "-x", "the cap side")
    assert Path(file) == out and front == [-1.0, 0.0, 0.0]
    cat = load_catalog(str(out))
    c = cat.categories["lib bottle"]
    assert c.front == (-1.0, 0.0, 0.0) and c.front_phrase == "the cap side"
    assert len(out.read_text().splitlines()) == len(before.splitlines()) + 2  # two lines added, nothing else moved
    set_front(cat, "lib bottle", "+y", "the label")  # replaces, does not add again
    assert len(out.read_text().splitlines()) == len(before.splitlines()) + 2
    with pytest.raises(KeyError):
        set_front(cat, "no such thing", "+x", "x")
    info = asset_sheet(tmp_path / "sheet.png", str(out), ["lib bottle", "lib brick"], px=96)
    im = np.asarray(Image.open(info["out"]))
    assert im.shape == (2 * 96, 7 * 96, 3)
    magenta = (im[..., 0] > 200) & (im[..., 1] < 90) & (im[..., 2] > 150)
    assert magenta[:96, : 6 * 96].sum() > 30 and magenta[96:, : 6 * 96].sum() > 30  # both fronts drawn


def test_imported_ycb_objects_render_with_their_labels(shared_data, tmp_path):
    """One command on the shared folder, then a scene: YCB objects come out textured, not black."""
    import os

    os.environ.setdefault("MUJOCO_GL", "egl")
    from refspatial_gen.sources.sim import generate

    if not (shared_data / "ycb_sim" / "objects.json").exists():
        pytest.skip("ycb_sim not in shared data")
    out = tmp_path / "ycb.yaml"
    rows = import_assets([shared_data / "ycb_sim"], out, cache=tmp_path / "cache", collision="hull")
    assert {r["label"] for r in rows} == {"cracker box", "tomato soup can", "mustard bottle", "gelatin box", "power drill"}
    assert "shared:ycb_sim/003_cracker_box/model.obj" in out.read_text()
    frames = generate("sim:000001", np.random.default_rng(1), {"catalog": str(out), "external_prob": 1.0, "width": 320,
                                                               "height": 240, "views": 1, "layouts": {"tabletop": 1.0},
                                                               "inside_prob": 0, "stack_prob": 0})
    f = frames[0]
    ycb = [o for o in f.objects if o.provenance["asset"].startswith("ycb_sim ")]
    assert ycb
    means = []
    for o in ycb:
        px = f.rgb[o.mask.decode()].astype(float)
        if len(px) > 200:
            assert px.std() > 15, o.category  # printed label: varied colours, not a flat black silhouette
            means.append(np.percentile(px.max(axis=1), 90))  # the bright part of the label (dark objects: a drill)
    assert means and max(means) > 100  # a black-rendered texture stays near 0
