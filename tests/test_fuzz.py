"""Fuzz: recipes, YAML, templates, catalogs and every input format, mutated at random (fixed seed).

The property everywhere: bad content is a RecipeError (recipes, templates, catalogs), an InputError
(a top-level input file) or a DropUnit (one unit's input) — never any other exception. The fast tests run
60 examples each; the slow ones 300."""

from __future__ import annotations

import itertools
import json
import shutil
from pathlib import Path

import numpy as np
import pytest
import yaml
from hypothesis import given
from hypothesis import strategies as st

from refspatial_gen.core.errors import DropUnit, InputError, RecipeError, RecipeErrors
from refspatial_gen.yamlpos import load_yaml
from tests.fuzzing import FAST, SLOW, json_values, mutate
from tests.helpers.runs import TEMPLATES

REPO = Path(__file__).resolve().parents[1]
_n = itertools.count()


def _fresh(tmp_path: Path, name: str) -> Path:
    """A new folder per example (readers cache by path)."""
    d = tmp_path / f"{name}-{next(_n)}"
    d.mkdir()
    return d


# ---------------------------------------------------------------------------------------------- recipes


@FAST
@given(st.text(max_size=400))
def test_any_text_is_data_or_a_recipe_error(text):
    try:
        load_yaml("r.yaml", text)
    except RecipeError:
        pass


@FAST
@given(json_values)
def test_any_yaml_document_loads_back_or_errors(value):
    try:
        data, _ = load_yaml("r.yaml", yaml.safe_dump(value))
    except RecipeError:
        return
    if not isinstance(value, float):  # NaN != NaN
        assert data == value


TOY = {"name": "t", "seed": 1, "scenes": 3, "sources": [{"kind": "toy", "weight": 1.0, "config": {"min_objects": 4}}],
       "qa": {"max_per_sample": 5, "families": {"locate": {"weight": 1.0, "templates": ["templates/locate.yaml"]},
                                                "choice": {"weight": 1.0, "templates": ["templates/choice.yaml"]}}},
       "shards": {"samples_per_shard": 2, "image_format": "png"}}


@FAST
@given(st.data())
def test_mutated_recipes_load_or_raise_recipe_errors(tmp_path_factory, data):
    from refspatial_gen.recipe import load_recipe

    d = tmp_path_factory.mktemp("recipe")
    (d / "templates").symlink_to(TEMPLATES)
    p = d / "r.yaml"
    p.write_text(yaml.safe_dump(mutate(TOY, data, rounds=3)))
    try:
        load_recipe(p)
    except (RecipeError, RecipeErrors):
        pass


def _template_docs() -> list[tuple[str, dict]]:
    return [(p.name, yaml.safe_load(p.read_text())) for p in sorted(TEMPLATES.glob("*.yaml"))]


@pytest.mark.slow
@SLOW
@given(st.data())
def test_mutated_templates_compile_or_report_errors(data):
    from refspatial_gen.qa.templates import compile_templates

    name, doc = data.draw(st.sampled_from(_template_docs()), label="file")
    text = yaml.safe_dump(mutate(doc, data, rounds=2))
    try:
        doc2, lines = load_yaml(name, text)
    except RecipeError:
        return
    errors: list[RecipeError] = []
    compile_templates(doc2, name, lines, errors)


@pytest.mark.slow
@SLOW
@given(st.data())
def test_mutated_catalogs_load_or_raise_recipe_errors(tmp_path_factory, data):
    from refspatial_gen.assets import load_catalog

    doc = yaml.safe_load((REPO / "assets" / "catalog.yaml").read_text())
    p = tmp_path_factory.mktemp("cat") / f"catalog-{next(_n)}.yaml"
    p.write_text(yaml.safe_dump(mutate(doc, data, rounds=2)))
    try:
        load_catalog(str(p))
    except (RecipeError, RecipeErrors):
        pass


# ---------------------------------------------------------------------------------------------- inputs


def _jpeg(path: Path, w: int, h: int, seed: int = 0) -> None:
    from PIL import Image

    path.parent.mkdir(parents=True, exist_ok=True)
    Image.fromarray(np.random.default_rng(seed).integers(0, 255, (h, w, 3), dtype=np.uint8)).save(path)


COCO = {"images": [{"id": 1, "file_name": "a.jpg", "width": 64, "height": 48},
                   {"id": 2, "file_name": "b.jpg", "width": 64, "height": 48}],
        "categories": [{"id": 1, "name": "cup"}, {"id": 2, "name": "table", "isthing": 1}],
        "annotations": [
            {"id": 10, "image_id": 1, "category_id": 1, "bbox": [4, 4, 10, 10], "iscrowd": 0,
             "segmentation": [[4, 4, 14, 4, 14, 14, 4, 14]]},
            {"id": 11, "image_id": 1, "category_id": 2, "bbox": [20, 20, 30, 20], "iscrowd": 0,
             "segmentation": {"size": [48, 64], "counts": [100, 20, 2952]}},
            {"id": 12, "image_id": 2, "category_id": 1, "bbox": [1, 1, 5, 5], "iscrowd": 0, "segmentation": []}]}


def _check_collection(coll) -> None:
    """Every record: invalid ones drop; valid ones give masks or drop with a reason."""
    from refspatial_gen.sources.image.annotations import annotation_mask
    from refspatial_gen.sources.image.checks import raise_if_invalid

    for rec in coll.images.values():
        try:
            raise_if_invalid(rec.meta)
            for ann in rec.annotations:
                annotation_mask(ann, rec, rec.width or 64, rec.height or 48)
        except DropUnit:
            pass


@FAST
@given(st.data())
def test_mutated_coco_files_drop_or_stop_planning(tmp_path_factory, data):
    from refspatial_gen.sources.image.annotations import load_collection

    root = tmp_path_factory.mktemp("coco")
    _jpeg(root / "images" / "a.jpg", 64, 48)
    _jpeg(root / "images" / "b.jpg", 64, 48, 1)
    (root / "instances.json").write_text(json.dumps(mutate(COCO, data, rounds=3)))
    try:
        coll = load_collection(root, data.draw(st.sampled_from(["auto", "coco"]), label="format"))
    except InputError:
        return
    _check_collection(coll)


@pytest.mark.slow
@SLOW
@given(st.data())
def test_mutated_openimages_csv(tmp_path_factory, data):
    from refspatial_gen.sources.image.annotations import load_collection

    root = tmp_path_factory.mktemp("oi")
    _jpeg(root / "images" / "img1.jpg", 64, 48)
    rows = [["ImageID", "LabelName", "XMin", "XMax", "YMin", "YMax", "IsGroupOf"],
            ["img1", "/m/cup", "0.1", "0.4", "0.1", "0.5", "0"], ["img1", "/m/tab", "0.5", "0.9", "0.5", "0.9", "0"]]
    cell = st.one_of(st.text(max_size=6), st.sampled_from(["nan", "inf", "-1", "1e309", "", "0.5"]))
    for _ in range(data.draw(st.integers(1, 3), label="n")):
        r, c = data.draw(st.integers(0, 2), label="row"), data.draw(st.integers(0, 6), label="col")
        rows[r][c] = data.draw(cell, label="cell").replace(",", ";").replace("\n", " ").replace("\r", " ")
    (root / "boxes.csv").write_text("\n".join(",".join(r) for r in rows) + "\n")
    try:
        coll = load_collection(root, "openimages")
    except InputError:
        return
    _check_collection(coll)


def _generic_scan(root: Path) -> dict:
    from tests.test_scan_formats import write_generic
    from refspatial_gen.sources.toy import toy_frame

    frames = [toy_frame(np.random.default_rng(s), 3, 96, 72, frame_id=f"t{s}") for s in (1, 2)]
    write_generic(root, frames)
    return json.loads((root / "scan.json").read_text())


@pytest.fixture(scope="module")
def generic_template(tmp_path_factory):
    root = tmp_path_factory.mktemp("generic") / "scan"
    return root, _generic_scan(root)


def _read_all(reader, root: Path, load: bool = False) -> None:
    from refspatial_gen.sources.scan.frames import view_to_frame
    from refspatial_gen.sources.scan.source import CONFIG_FIELDS

    cfg = {k: f.default for k, f in CONFIG_FIELDS.items()} | {"blur_threshold": 0.0, "min_visible_objects": 0}
    try:
        views = reader.views(root, cfg)
    except InputError:
        return
    for v in views[:3]:
        try:
            view = reader.read(root, v, cfg)
            if load:
                view_to_frame(view, cfg)
        except DropUnit:
            pass


@FAST
@given(st.data())
def test_mutated_generic_scans_drop_or_stop_planning(generic_template, tmp_path_factory, data):
    from refspatial_gen.sources.scan.readers.generic import GenericReader

    src, meta = generic_template
    root = tmp_path_factory.mktemp("g") / "scan"
    shutil.copytree(src, root)
    (root / "scan.json").write_text(json.dumps(mutate(meta, data, rounds=3)))
    _read_all(GenericReader(), root)


@pytest.mark.slow
@SLOW
@given(st.data())
def test_mutated_generic_scans_through_frame_building(generic_template, tmp_path_factory, data):
    from refspatial_gen.sources.scan.readers.generic import GenericReader

    src, meta = generic_template
    root = tmp_path_factory.mktemp("gl") / "scan"
    shutil.copytree(src, root)
    (root / "scan.json").write_text(json.dumps(mutate(meta, data, rounds=2)))
    _read_all(GenericReader(), root, load=True)


PLY_HEAD = b"ply\nformat binary_little_endian 1.0\nelement vertex 4\nproperty float x\nproperty float y\n" \
           b"property float z\nproperty uchar red\nproperty uchar green\nproperty uchar blue\nend_header\n"


@FAST
@given(st.data())
def test_mutated_ply_files_drop(tmp_path_factory, data):
    from refspatial_gen.sources.scan.readers.common import read_ply_xyz

    body = np.zeros(4, dtype=[("x", "<f4"), ("y", "<f4"), ("z", "<f4"), ("r", "u1"), ("g", "u1"), ("b", "u1")])
    raw = bytearray(PLY_HEAD + body.tobytes())
    if data.draw(st.booleans(), label="ascii"):
        raw = bytearray(PLY_HEAD.replace(b"binary_little_endian", b"ascii") + b"0 0 0 1 2 3\n" * 4)
    for _ in range(data.draw(st.integers(1, 4), label="edits")):
        op = data.draw(st.sampled_from(["cut", "byte", "insert"]), label="op")
        i = data.draw(st.integers(0, max(0, len(raw) - 1)), label="at")
        if op == "cut":
            del raw[i:]
        elif op == "byte" and raw:
            raw[i] = data.draw(st.integers(0, 255), label="b")
        else:
            raw[i:i] = data.draw(st.sampled_from([b"element vertex 99999999999\n", b"property list uchar int x\n",
                                                  b"property quad w\n", b"nan ", b"\n", b"end_header\n"]), label="ins")
    p = tmp_path_factory.mktemp("ply") / "p.ply"
    p.write_bytes(bytes(raw))
    try:
        xyz, _ = read_ply_xyz(p)
        assert np.all(np.isfinite(xyz))
    except DropUnit:
        pass


# ------------------------------------------------------------------------------- real samples (shared data)


def _shared(shared_data, name):
    p = shared_data / name
    if not p.exists():
        pytest.skip(f"{p} not found")
    return p


@pytest.mark.slow
@SLOW
@given(st.data())
def test_mutated_scannet_scene_json(shared_data, tmp_path_factory, data):
    from refspatial_gen.sources.scan.readers.scannet import ScanNetReader

    src = _shared(shared_data, "scannet_scene0000_00")
    root = tmp_path_factory.mktemp("sn") / "scene"
    root.mkdir()
    (root / "color").symlink_to(src / "color")
    (root / "points_raw.ply").symlink_to(src / "points_raw.ply")
    meta = json.loads((src / "scene.json").read_text())
    (root / "scene.json").write_text(json.dumps(mutate(meta, data, rounds=2)))
    _read_all(ScanNetReader(), root)


@pytest.mark.slow
@SLOW
@given(st.data())
def test_mutated_sunrgbd_annotation_json(shared_data, tmp_path_factory, data):
    from refspatial_gen.sources.image.annotations import read_sunrgbd
    from refspatial_gen.sources.scan.readers.sunrgbd import SunRGBDReader

    src = _shared(shared_data, "sunrgbd")
    root = tmp_path_factory.mktemp("sun")
    d = root / "000001"
    d.mkdir()
    for f in ("image.jpg", "depth.png"):
        (d / f).symlink_to(src / "000001" / f)
    ann = json.loads((src / "000001" / "annotation.json").read_text())
    (d / "annotation.json").write_text(json.dumps(mutate(ann, data, rounds=2)))
    _read_all(SunRGBDReader(), root)
    _check_collection(read_sunrgbd(root))


@pytest.mark.slow
@SLOW
@given(st.data())
def test_mutated_trajectory_files(shared_data, tmp_path_factory, data):
    from refspatial_gen.sources.scan.readers.trajectory import TrajectoryReader

    src = _shared(shared_data, "open3d_rgbd/icl_nuim_livingroom")
    root = tmp_path_factory.mktemp("traj") / "seq"
    root.mkdir()
    for f in ("color", "depth"):
        (root / f).symlink_to(src / f)
    log = (src / "trajectory.log").read_text().split()
    for _ in range(data.draw(st.integers(1, 3), label="n")):
        i = data.draw(st.integers(0, len(log) - 1), label="i")
        log[i] = data.draw(st.sampled_from(["nan", "x", "1e999", "", "0 0"]), label="tok")
    (root / "trajectory.log").write_text(" ".join(log[:data.draw(st.integers(0, len(log)), label="cut")]))
    cam = json.loads((src / "camera_primesense.json").read_text())
    (root / "camera_primesense.json").write_text(json.dumps(mutate(cam, data, rounds=1)))
    _read_all(TrajectoryReader(), root)


@pytest.fixture(scope="module")
def mcap_recording(tmp_path_factory):
    from tests.test_scan_formats import _write_mcap
    from refspatial_gen.sources.toy import toy_frame

    p = tmp_path_factory.mktemp("mcap") / "rec.mcap"
    _write_mcap(p, [toy_frame(np.random.default_rng(s), 3, 96, 72, frame_id=f"t{s}") for s in (1, 2)])
    return p.read_bytes()


@FAST
@given(st.data())
def test_damaged_mcap_recordings_drop_or_stop_planning(mcap_recording, tmp_path_factory, data):
    from refspatial_gen.sources.scan.readers.mcap_reader import McapReader

    raw = bytearray(mcap_recording)
    if data.draw(st.booleans(), label="cut"):
        del raw[data.draw(st.integers(0, len(raw) - 1), label="at"):]
    else:
        for _ in range(data.draw(st.integers(1, 6), label="n")):
            raw[data.draw(st.integers(0, len(raw) - 1), label="i")] = data.draw(st.integers(0, 255), label="b")
    root = tmp_path_factory.mktemp("rec")
    (root / "rec.mcap").write_bytes(bytes(raw))
    try:
        _read_all(McapReader(), root)
    except DropUnit:
        pass  # the recording's index cannot be read: planning turns this into `path: message`
