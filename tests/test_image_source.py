"""Image source: real COCO/panoptic frames with geometric depth, a synthetic RGB-D collection with known
3D boxes (provided depth), OpenImages CSVs, and the whole-image drop reasons."""

import json
from pathlib import Path

import numpy as np
import pytest

from refspatial_gen.core.errors import DropUnit, RecipeErrors
from refspatial_gen.core.mask import answer_pixel
from refspatial_gen.core.serialize import dumps
from refspatial_gen.sources import get_source
from refspatial_gen.sources.image import ImageSource, parse_key, unit_key
from refspatial_gen.sources.image.rle import encode_counts_string
from refspatial_gen.truth.sizes import UNRANGED, can_bear, check_size

pytest.importorskip("open3d")


# ------------------------------------------------------------------ a synthetic collection with ground truth


def write_toy_collection(root: Path, n: int = 2, depth: bool = True, seed: int = 3) -> list:
    """Toy box-world frames written as a COCO collection (PNG images, compressed-RLE masks, mm depth PNGs
    and intrinsics sidecars). Returns the toy Frames (the ground truth)."""
    import cv2

    from refspatial_gen.sources.toy import toy_frame

    (root / "images").mkdir(parents=True, exist_ok=True)
    rng = np.random.default_rng(seed)
    images, anns, frames = [], [], []
    cats = sorted({"box", "book", "can", "block", "tray"})
    for i in range(n):
        f = toy_frame(rng, 5, 320, 240, frame_id=f"toy{i}")
        frames.append(f)
        name = f"{i:06d}.png"
        cv2.imwrite(str(root / "images" / name), f.rgb[..., ::-1])
        if depth:
            cv2.imwrite(str(root / "images" / f"{i:06d}_depth.png"), np.round(f.depth * 1000).astype(np.uint16))
        K = f.camera.K  # the toy and the image source share Camera's convention (pixel u spans [u, u+1))
        (root / "images" / f"{i:06d}.intrinsics.json").write_text(json.dumps({"K": K.tolist()}))
        images.append({"id": i + 1, "file_name": name, "width": 320, "height": 240})
        for o in f.objects:
            x0, y0, x1, y1 = o.bbox2d
            anns.append({"id": 100 * (i + 1) + o.id, "image_id": i + 1, "category_id": cats.index(o.category) + 1,
                         "iscrowd": 0, "bbox": [x0, y0, x1 - x0, y1 - y0], "area": o.mask.area,
                         "segmentation": {"size": [240, 320], "counts": encode_counts_string(list(o.mask.counts))}})
    (root / "instances.json").write_text(json.dumps(
        {"images": images, "annotations": anns, "categories": [{"id": k + 1, "name": c} for k, c in enumerate(cats)]}))
    return frames


TOY_CFG = {"depth": {"estimator": "provided", "encoding": "mm"}, "intrinsics": "provided",
           "camera_pitch_deg": 45.0, "complete_categories": False, "min_objects": 1, "min_instance_spread": 0.0,
           "min_mask_area": 30}


def test_synthetic_rgbd_lifting_matches_ground_truth(tmp_path):
    truth = write_toy_collection(tmp_path, n=2)
    src = ImageSource()
    keys = src.unit_keys(TOY_CFG, None, str(tmp_path))
    assert keys == ["image:1", "image:2"] and [parse_key(k) for k in keys] == ["1", "2"]
    errs, height_errs = [], []
    for k, gt in zip(keys, truth):
        f = src.load(k, np.random.default_rng(0), TOY_CFG | {"_input": str(tmp_path)})[0]
        f.validate()
        assert f.camera.gravity_known and f.meta["gravity"]["origin"] == "plane_ransac"
        up_gt = gt.camera.cam_from_world[:3, :3] @ np.array([0, 0, 1.0])
        up = f.camera.cam_from_world[:3, :3] @ np.array([0, 0, 1.0])
        assert np.degrees(np.arccos(np.clip(up @ up_gt, -1, 1))) < 2.0
        from refspatial_gen.sources.toy import TABLE

        # the floor is not in view: the camera height is measured above the table top
        assert abs(f.meta["gravity"]["camera_height"] - (gt.camera.position[2] - TABLE.top_z)) < 0.01
        by_ann = {int(o.provenance["annotation_id"]) % 100: o for o in f.objects}
        for g in gt.objects:
            o = by_ann.get(g.id)
            if o is None or g.mask.area < 200:
                continue
            c_lift = f.camera.world_to_cam(o.box.center)[0]
            c_gt = gt.camera.world_to_cam(g.box.center)[0]
            errs.append(np.linalg.norm(c_lift - c_gt))
            height_errs.append(abs(o.box.height - g.box.height))
    assert len(errs) >= 6
    print(f"synthetic RGB-D: median centre error {100 * np.median(errs):.1f} cm, height {100 * np.median(height_errs):.1f} cm")
    assert np.median(errs) < 0.03
    assert np.median(height_errs) < 0.02


def test_frames_are_reproducible(tmp_path):
    write_toy_collection(tmp_path, n=1)
    src = ImageSource()
    k = src.unit_keys(TOY_CFG, None, str(tmp_path))[0]
    cfg = TOY_CFG | {"_input": str(tmp_path)}
    a = src.load(k, np.random.default_rng(5), cfg)[0]
    b = src.load(k, np.random.default_rng(5), cfg)[0]
    assert dumps(a.meta_json()) == dumps(b.meta_json())
    assert np.array_equal(a.depth, b.depth)


def test_keys_and_frames_do_not_depend_on_the_folder(tmp_path):
    """The same collection in two differently named folders: same keys, same frames (same rng seed)."""
    import shutil

    first = tmp_path / "a" / "collection"
    write_toy_collection(first, n=2)
    second = tmp_path / "elsewhere" / "renamed_copy"
    shutil.copytree(first, second)
    src = ImageSource()
    ka = src.unit_keys(TOY_CFG, None, str(first))
    kb = src.unit_keys(TOY_CFG, None, str(second))
    assert ka == kb == ["image:1", "image:2"]
    assert not any(str(tmp_path) in k for k in ka)
    for k in ka:
        fa = src.load(k, np.random.default_rng(7), TOY_CFG | {"_input": str(first)})[0]
        fb = src.load(k, np.random.default_rng(7), TOY_CFG | {"_input": str(second)})[0]
        assert fa.frame_id == fb.frame_id == k
        assert dumps(fa.meta_json()) == dumps(fb.meta_json())
        assert str(tmp_path).encode() not in dumps(fa.meta_json())
        assert np.array_equal(fa.rgb, fb.rgb) and np.array_equal(fa.depth, fb.depth)
    # the collection is read from `_input`: a key alone is not enough
    with pytest.raises(ValueError, match="_input"):
        src.load(ka[0], np.random.default_rng(7), TOY_CFG)


# ------------------------------------------------------------------ whole-image drops


def _expect_drop(root: Path, cfg: dict, reason: str) -> None:
    src = ImageSource()
    keys = src.unit_keys(cfg, None, str(root))
    reasons = []
    for k in keys:
        try:
            src.load(k, np.random.default_rng(0), cfg | {"_input": str(root)})
            reasons.append(None)
        except DropUnit as e:
            reasons.append(e.reason)
    assert reasons[0] == reason, reasons
    assert reasons[1] is None, reasons  # the other image of the collection still works


def test_corrupt_image_drops_that_image(tmp_path):
    write_toy_collection(tmp_path, n=2)
    p = tmp_path / "images" / "000000.png"
    p.write_bytes(p.read_bytes()[:300])  # truncated PNG
    _expect_drop(tmp_path, TOY_CFG, "image_undecodable")


def test_annotation_outside_image_drops_that_image(tmp_path):
    write_toy_collection(tmp_path, n=2)
    d = json.loads((tmp_path / "instances.json").read_text())
    a = next(a for a in d["annotations"] if a["image_id"] == 1)
    a["bbox"] = [300.0, 10.0, 60.0, 20.0]  # x1 = 360 in a 320-wide image
    (tmp_path / "instances.json").write_text(json.dumps(d))
    _expect_drop(tmp_path, TOY_CFG, "annotation_out_of_bounds")


def test_polygon_outside_image_drops_that_image(tmp_path):
    write_toy_collection(tmp_path, n=2)
    d = json.loads((tmp_path / "instances.json").read_text())
    a = next(a for a in d["annotations"] if a["image_id"] == 1)
    a["segmentation"] = [[10.0, 10.0, 40.0, 10.0, 40.0, 260.0]]  # y = 260 in a 240-high image
    a["bbox"] = [10.0, 10.0, 30.0, 230.0]
    (tmp_path / "instances.json").write_text(json.dumps(d))
    _expect_drop(tmp_path, TOY_CFG, "annotation_out_of_bounds")


def test_depth_of_the_wrong_size_drops_that_image(tmp_path):
    import cv2

    write_toy_collection(tmp_path, n=2)
    cv2.imwrite(str(tmp_path / "images" / "000000_depth.png"), np.full((120, 160), 1500, np.uint16))
    _expect_drop(tmp_path, TOY_CFG, "depth_size_mismatch")


def test_image_of_another_size_than_annotated_is_dropped(tmp_path):
    import cv2

    write_toy_collection(tmp_path, n=2)
    cv2.imwrite(str(tmp_path / "images" / "000000.png"), np.zeros((100, 100, 3), np.uint8))
    _expect_drop(tmp_path, TOY_CFG, "image_size_mismatch")


# ------------------------------------------------------------------ real photos, geometric depth


def test_coco_geometric_frames(shared_data):
    root = shared_data / "coco_tiny_train2017"
    src = get_source("image")
    keys = src.unit_keys({}, None, str(root))
    assert len(keys) == 50 and keys == sorted(keys)
    frames, reasons = [], {}
    for k in keys[:24]:
        try:
            frames.append(src.load(k, np.random.default_rng(0), {"_input": str(root)})[0])
        except DropUnit as e:
            reasons[e.reason] = reasons.get(e.reason, 0) + 1
    assert len(frames) >= 6, reasons
    assert set(reasons) <= {"too_few_objects"}
    for f in frames:
        f.validate()
        assert f.camera.gravity_known and f.meta["gravity"]["origin"] == "prior"
        assert f.meta["intrinsics"]["origin"] == "fov_prior"
        assert f.meta["depth"]["origin"].startswith("geometric")
        cats = [o.category for o in f.objects]
        dropped_cats = {d["category"] for d in f.meta["dropped_object_list"]}
        assert not dropped_cats & set(cats)  # no category is half kept: references stay unique
        for o in f.objects:
            m = o.mask.decode()
            assert m.any() and o.bbox2d is not None
            x, y = answer_pixel(m)
            assert f.depth[int(y), int(x)] > 0
            assert np.all(o.box.size > 0) and np.all(o.box.size < 30)
            # the box projects onto its object: projected centre column inside the mask's columns (+- 10%)
            u = f.camera.project(o.box.center)[0][0, 0]
            x0, _, x1, _ = o.bbox2d
            assert x0 - 0.1 * f.camera.width <= u <= x1 + 0.1 * f.camera.width
            if o.provenance.get("contact") == "ground":
                assert abs(o.box.bottom_z) < 0.02  # standing on the ground plane of the prior
            # truth checks: what stays is inside its category's range; it rests only on what can bear it
            assert check_size(o.category, o.box.size, dims=("height",)) in (None, UNRANGED) \
                or o.provenance.get("size_check") != "in_range"
            if "rests_on" in o.provenance:
                assert can_bear(o.provenance["rests_on"]["category"], o.category)
        # front/behind agrees with the image for ground contacts: lower in the image = nearer
        ground = [o for o in f.objects if o.provenance.get("contact") == "ground"]
        for a in ground:
            for b in ground:
                if a.bbox2d[3] > b.bbox2d[3] + 5:
                    assert f.camera.world_to_cam(a.box.center)[0][2] < f.camera.world_to_cam(b.box.center)[0][2] + 1e-6


def test_coco_panoptic_uses_ground_stuff(shared_data):
    src = ImageSource()
    root = shared_data / "coco_panoptic_sample"
    keys = src.unit_keys({}, None, str(root))
    assert len(keys) == 2
    frames = []
    for k in keys:
        try:
            frames.append(src.load(k, np.random.default_rng(0), {"_input": str(root)})[0])
        except DropUnit as e:
            assert e.reason == "too_few_objects"
    assert frames
    f = frames[0]
    assert f.meta["annotation_format"] == "coco_panoptic"
    assert any(s.kind == "floor" for s in f.surfaces)  # road/pavement stuff -> the ground surface
    assert all(o.provenance["mask"] == "segmentation" for o in f.objects)


# ------------------------------------------------------------------ OpenImages CSVs


def _write_openimages(root: Path, with_masks: bool) -> None:
    import cv2

    (root / "images").mkdir(parents=True)
    img = np.full((200, 300, 3), 120, np.uint8)
    img[120:190, 40:100] = (200, 40, 40)  # a "chair" standing on the ground
    img[100:180, 180:260] = (40, 40, 200)  # a "table", farther
    cv2.imwrite(str(root / "images" / "abc123.jpg"), img)
    (root / "class-descriptions-boxable.csv").write_text("/m/01mzpv,Chair\n/m/04bcr3,Table\n")
    rows = ["ImageID,Source,LabelName,Confidence,XMin,XMax,YMin,YMax,IsOccluded,IsTruncated,IsGroupOf,IsDepiction,IsInside",
            "abc123,xclick,/m/01mzpv,1,0.1333,0.3333,0.6,0.95,0,0,0,0,0",
            "abc123,xclick,/m/04bcr3,1,0.6,0.8667,0.5,0.9,0,0,0,0,0"]
    (root / "train-annotations-bbox.csv").write_text("\n".join(rows) + "\n")
    if with_masks:
        (root / "masks").mkdir()
        m1 = np.zeros((100, 150), np.uint8)
        m1[60:95, 20:50] = 255
        m2 = np.zeros((100, 150), np.uint8)
        m2[50:90, 90:130] = 255
        cv2.imwrite(str(root / "masks" / "abc123_m01mzpv_a.png"), m1)
        cv2.imwrite(str(root / "masks" / "abc123_m04bcr3_b.png"), m2)
        rows = ["MaskPath,ImageID,LabelName,BoxID,BoxXMin,BoxXMax,BoxYMin,BoxYMax,PredictedIoU,Clicks",
                "abc123_m01mzpv_a.png,abc123,/m/01mzpv,a,0.1333,0.3333,0.6,0.95,0.9,",
                "abc123_m04bcr3_b.png,abc123,/m/04bcr3,b,0.6,0.8667,0.5,0.9,0.9,"]
        (root / "train-annotations-object-segmentation.csv").write_text("\n".join(rows) + "\n")


@pytest.mark.parametrize("with_masks", [False, True])
def test_openimages_boxes_and_masks(tmp_path, with_masks):
    _write_openimages(tmp_path, with_masks)
    src = ImageSource()
    keys = src.unit_keys({}, None, str(tmp_path))
    assert keys == [unit_key("abc123")] == ["image:abc123"]
    f = src.load(keys[0], np.random.default_rng(0), {"depth": {"estimator": "geometric", "size_fallback": False},
                                                     "_input": str(tmp_path)})[0]
    f.validate()
    assert f.meta["annotation_format"] == "openimages"
    by = {o.category: o for o in f.objects}
    assert set(by) == {"Chair", "Table"}
    assert by["Chair"].provenance["mask"] == ("segmentation" if with_masks else "box")
    # the chair's bottom is lower in the image: it is nearer
    zc = f.camera.world_to_cam(by["Chair"].box.center)[0][2]
    zt = f.camera.world_to_cam(by["Table"].box.center)[0][2]
    assert zc < zt


# ------------------------------------------------------------------ recipe checks


def test_recipe_rejects_bad_depth_options(tmp_path):
    from refspatial_gen.recipe import load_recipe

    (tmp_path / "r.yaml").write_text(
        "name: x\nsources:\n  - kind: image\n    config:\n      depth:\n        estimator: geometric\n"
        "        camera_hight: 1.4\n")
    with pytest.raises(RecipeErrors) as e:
        load_recipe(tmp_path / "r.yaml")
    assert "r.yaml:5" in str(e.value) and "unknown option" in str(e.value) and "camera_height" in str(e.value)
    (tmp_path / "r2.yaml").write_text(
        "name: x\nsources:\n  - kind: image\n    config:\n      depth: {estimator: depth-anything, model_dir: /nonexistent}\n"
        "qa:\n  families:\n    locate: {weight: 1.0, templates: [templates/locate.yaml]}\n")
    with pytest.raises(RecipeErrors) as e:
        load_recipe(tmp_path / "r2.yaml")
    assert "never downloaded" in str(e.value)


@pytest.mark.parametrize(
    "key,value,line,words",
    [
        ("incomplete_categories", "[[1, 2]]", 5, "list of category names"),
        ("incomplete_categories", "[person, 3]", 5, "list of category names"),
        ("categories", "[cup, '']", 5, "list of category names"),
        ("foot_border_margin", "0.9", 5, "<= 0.5"),
        ("incomplete_min_instances", "0", 5, ">= 1"),
        ("composite_max_std", "300", 5, "<= 255"),
    ],
)
def test_recipe_rejects_bad_photo_rule_keys(tmp_path, key, value, line, words):
    """The photo truth rules' keys are checked before any work, with file:line (a non-string category
    name used to pass: reliability mutation `incomplete_categories.0 of the wrong type`)."""
    from refspatial_gen.recipe import load_recipe

    (tmp_path / "r.yaml").write_text(f"name: x\nsources:\n  - kind: image\n    config:\n      {key}: {value}\n")
    with pytest.raises(RecipeErrors) as e:
        load_recipe(tmp_path / "r.yaml", input_path="/tmp")
    assert f"r.yaml:{line}" in str(e.value) and words in str(e.value) and key in str(e.value)


def test_shipped_recipes_load():
    from refspatial_gen.recipe import load_recipe

    r = load_recipe(Path(__file__).resolve().parents[1] / "recipes" / "image.yaml", input_path="/tmp")
    assert r.sources[0].kind == "image" and r.sources[0].config["depth"]["estimator"] == "geometric"


def test_bench_helper(shared_data):
    from refspatial_gen.sources.image.bench import per_image_ms

    b = per_image_ms(str(shared_data / "coco_tiny_train2017"), limit=6)
    assert b["images"] == 6 and b["frames"] + sum(b["dropped"].values()) == 6
    assert b["ms_per_image"] > 0 and "lift" in b["stages_ms"]
    print("image source bench (6 images):", b)
