"""Broken scene inputs, built from copies of ../shared/data: each must be a counted drop or a `path:` error.

Every case copies a small sample into a temporary folder, damages one thing, and runs
`refspatial-gen shards` on it with the shipped recipe. Image cases use a three-image COCO subset (the
first image and its first annotation are the damaged ones).
"""

from __future__ import annotations

import json
import os
from pathlib import Path
from typing import Any, Callable

from relrun import REPO, Case, writable_copy

RECIPES = REPO / "recipes"
MINI_COCO_IMAGES = 3


def _shards(recipe: str, inp: Path, out: Path, scenes: int) -> list[str]:
    return ["shards", "--recipe", str(RECIPES / recipe), "--input", str(inp), "--out", str(out), "--workers", "1",
            "--quiet", "--no-report", "--scenes", str(scenes)]


def edit_json(path: Path, fn: Callable[[Any], Any]) -> None:
    data = json.loads(path.read_text())
    fn(data)  # edits in place (its return value is ignored)
    path.write_text(json.dumps(data))


def truncate(path: Path, keep: float = 0.5) -> None:
    raw = path.read_bytes()
    path.write_bytes(raw[: int(len(raw) * keep)])


def mini_coco(data: Path, dst: Path) -> Path:
    """The first MINI_COCO_IMAGES images (by id) of coco_tiny with their annotations and files."""
    src = data / "coco_tiny_train2017"
    d = json.loads((src / "instances.json").read_text())
    ims = sorted(d["images"], key=lambda i: i["id"])[:MINI_COCO_IMAGES]
    ids = {i["id"] for i in ims}
    (dst / "images").mkdir(parents=True)
    for im in ims:
        (dst / "images" / im["file_name"]).write_bytes((src / "images" / im["file_name"]).read_bytes())
    d["images"] = ims
    d["annotations"] = [a for a in d["annotations"] if a["image_id"] in ids]
    (dst / "instances.json").write_text(json.dumps(d))
    return dst


def _first(d: dict) -> tuple[dict, dict]:
    """The damaged image entry and its first annotation."""
    im = d["images"][0]
    return im, next(a for a in d["annotations"] if a["image_id"] == im["id"])


def coco_case(name: str, damage: Callable[[Path, dict, dict, dict], None], expect: str,
              reasons: tuple[str, ...] = ()) -> Callable[[Path], Case]:
    def make(data: Path) -> Case:
        def setup(tmp: Path):
            root = mini_coco(data, tmp / "coco")
            d = json.loads((root / "instances.json").read_text())
            im, ann = _first(d)
            damage(root, d, im, ann)
            if not d.pop("_raw", False):
                (root / "instances.json").write_text(json.dumps(d))
            return _shards("image.yaml", root, tmp / "out", MINI_COCO_IMAGES), tmp / "out"
        return Case("coco", name, setup, expect, reasons)
    return make


def _set(obj: str, key: str, value: Any) -> Callable:
    def damage(root, d, im, ann):
        (ann if obj == "ann" else im)[key] = value
    return damage


def _del(obj: str, key: str) -> Callable:
    return lambda root, d, im, ann: (ann if obj == "ann" else im).pop(key, None)


def _raw(fn: Callable[[Path], None]) -> Callable:
    def damage(root, d, im, ann):
        d["_raw"] = True
        fn(root)
    return damage


def _imgfile(fn: Callable[[Path], None]) -> Callable:
    return lambda root, d, im, ann: fn(root / "images" / im["file_name"])


AI = ("annotation_invalid",)
COCO = [
    ("annotation bbox is a string", _set("ann", "bbox", "wide"), "drop", AI),
    ("annotation bbox missing", _del("ann", "bbox"), "drop", AI),
    ("annotation bbox has 3 numbers", _set("ann", "bbox", [1, 2, 3]), "drop", AI),
    ("annotation bbox holds NaN", _set("ann", "bbox", [float("nan"), 1, 2, 3]), "drop", AI),
    ("annotation bbox has a negative width", _set("ann", "bbox", [10, 10, -5, 5]), "drop", AI),
    ("annotation bbox is null", _set("ann", "bbox", None), "drop", AI),
    ("annotation category_id missing", _del("ann", "category_id"), "drop", AI),
    ("annotation category_id is a string", _set("ann", "category_id", "4"), "drop", AI),
    ("annotation category_id not in categories", _set("ann", "category_id", 9999), "drop", AI),
    ("annotation id missing", _del("ann", "id"), "drop", AI),
    ("annotation id is a string", _set("ann", "id", "x"), "drop", AI),
    ("annotation image_id missing", _del("ann", "image_id"), "drop", AI),
    ("annotation image_id is a list", _set("ann", "image_id", [1]), "drop", AI),
    ("segmentation is a string", _set("ann", "segmentation", "polygon"), "drop", AI),
    ("segmentation polygon has an odd count", _set("ann", "segmentation", [[1, 2, 3, 4, 5, 6, 7]]), "drop", AI),
    ("segmentation polygon holds a string", _set("ann", "segmentation", [[1, 2, "x", 4, 5, 6]]), "drop", AI),
    ("segmentation RLE counts are strings", _set("ann", "segmentation", {"size": [10, 10], "counts": ["a"]}),
     "drop", AI),
    ("segmentation RLE of the wrong size", _set("ann", "segmentation", {"size": [1, 1], "counts": [1]}),
     "drop", ("annotation_size_mismatch",)),
    ("segmentation polygon far outside the image", _set("ann", "segmentation", [[5000, 5000, 6000, 5000, 6000, 6000]]),
     "drop", ("annotation_out_of_bounds",)),
    ("annotation iscrowd is 'yes'", _set("ann", "iscrowd", "yes"), "drop", AI),
    ("annotation entry is a number", lambda root, d, im, ann: d["annotations"].__setitem__(0, 7), "drop", AI),
    ("image width is 'wide'", _set("im", "width", "wide"), "drop", AI),
    ("image height is 0", _set("im", "height", 0), "drop", AI),
    ("image width is negative", _set("im", "width", -640), "drop", AI),
    ("image file_name missing", _del("im", "file_name"), "drop", AI),
    ("image file_name climbs out (../../etc/passwd)", _set("im", "file_name", "../../../../etc/passwd"), "drop",
     ("path_outside_input",)),
    ("image file_name is absolute (/etc/passwd)", _set("im", "file_name", "/etc/passwd"), "drop", ("path_outside_input",)),
    ("image id missing", _del("im", "id"), "drop", AI),
    ("image id listed twice", lambda root, d, im, ann: d["images"].append(dict(im)), "drop", AI),
    ("image entry is a string", lambda root, d, im, ann: d["images"].__setitem__(0, "img"), "drop", AI),
    ("image width disagrees with the file", lambda root, d, im, ann: im.__setitem__("width", im["width"] + 1), "drop",
     ("image_size_mismatch",)),
    ("image file truncated", _imgfile(lambda p: p.write_bytes(p.read_bytes()[:2000])), "drop", ("image_undecodable",)),
    ("image file empty", _imgfile(lambda p: p.write_bytes(b"")), "drop", ("image_undecodable",)),
    ("image file missing", _imgfile(lambda p: p.unlink()), "drop", ("image_missing",)),
    ("image file is a folder", _imgfile(lambda p: (p.unlink(), p.mkdir())), "drop", ("image_missing",)),
    ("image file is text", _imgfile(lambda p: p.write_text("not a jpeg")), "drop", ("image_undecodable",)),
    ("categories entry without a name", lambda root, d, im, ann: [c.pop("name") for c in d["categories"]
                                                                   if c["id"] == ann["category_id"]], "drop", AI),
    ("instances.json truncated", _raw(lambda r: truncate(r / "instances.json")), "error"),
    ("instances.json empty", _raw(lambda r: (r / "instances.json").write_bytes(b"")), "error"),
    ("instances.json binary garbage", _raw(lambda r: (r / "instances.json").write_bytes(bytes(range(256)) * 8)), "error"),
    ("instances.json is a JSON list", _raw(lambda r: (r / "instances.json").write_text("[1, 2]")), "error"),
    ("`images` is a string", lambda root, d, im, ann: d.__setitem__("images", "all"), "error"),
    ("`annotations` is a mapping", lambda root, d, im, ann: d.__setitem__("annotations", {"a": 1}), "error"),
    ("`categories` missing", lambda root, d, im, ann: d.pop("categories"), "error"),
    ("instances.json nested 100000 deep", _raw(lambda r: (r / "instances.json").write_text("[" * 100000 + "]" * 100000)),
     "error"),
    ("instances.json is a folder", _raw(lambda r: ((r / "instances.json").unlink(), (r / "instances.json").mkdir())),
     "error"),
]


def panoptic_case(name: str, damage: Callable[[Path, dict], None], expect: str,
                  reasons: tuple[str, ...] = ()) -> Callable[[Path], Case]:
    def make(data: Path) -> Case:
        def setup(tmp: Path):
            root = writable_copy(data / "coco_panoptic_sample", tmp / "pan")
            (root / "panoptic_coco_detection_format.json").unlink()  # the panoptic file alone
            p = root / "panoptic_examples.json"
            d = json.loads(p.read_text())
            d["annotations"].sort(key=lambda a: str(a["image_id"]))
            damage(root, d)
            if not d.pop("_raw", False):
                p.write_text(json.dumps(d))
            return _shards("image.yaml", root, tmp / "out", 2), tmp / "out"
        return Case("coco_panoptic", name, setup, expect, reasons)
    return make


def _seg(fn: Callable[[dict], None]) -> Callable:
    return lambda root, d: fn(d["annotations"][0]["segments_info"][0])


def _png(fn: Callable[[Path], None]) -> Callable:
    return lambda root, d: fn(root / "panoptic_examples" / d["annotations"][0]["file_name"])


PANOPTIC = [
    ("panoptic JSON truncated", lambda root, d: (d.__setitem__("_raw", True), truncate(root / "panoptic_examples.json")),
     "error"),
    ("segments_info is a string", lambda root, d: d["annotations"][0].__setitem__("segments_info", "x"), "drop", AI),
    ("segment bbox is a string", _seg(lambda s: s.__setitem__("bbox", "box")), "drop", AI),
    ("segment category_id unknown", _seg(lambda s: s.__setitem__("category_id", 100000)), "drop", AI),
    ("segment id missing", _seg(lambda s: s.pop("id")), "drop", AI),
    ("panoptic PNG missing", _png(lambda p: p.unlink()), "drop", ("annotation_missing",)),
    ("panoptic PNG truncated", _png(lambda p: truncate(p, 0.3)), "drop", ("annotation_unreadable",)),
    ("panoptic PNG of the wrong size", _png(lambda p: _small_png(p)), "drop", ("annotation_size_mismatch",)),
    ("panoptic file_name climbs out", lambda root, d: d["annotations"][0].__setitem__("file_name", "../../x.png"),
     "drop", ("path_outside_input",)),
]


def _small_png(p: Path) -> None:
    import numpy as np
    from PIL import Image

    Image.fromarray(np.zeros((8, 8, 3), np.uint8)).save(p)


def sun_case(source: str, name: str, damage: Callable[[Path], None], expect: str,
             reasons: tuple[str, ...] = ()) -> Callable[[Path], Case]:
    """SUN RGB-D sample 000001 damaged, read by the scan source (scan.yaml) or as photos (image.yaml)."""
    def make(data: Path) -> Case:
        def setup(tmp: Path):
            root = writable_copy(data / "sunrgbd", tmp / "sun")
            damage(root / "000001")
            recipe = "scan.yaml" if source == "scan" else "image.yaml"
            return _shards(recipe, root, tmp / "out", 2), tmp / "out"
        return Case(f"sunrgbd ({source})", name, setup, expect, reasons)
    return make


def _ann(fn: Callable[[dict], None]) -> Callable[[Path], None]:
    return lambda d: edit_json(d / "annotation.json", fn)


SUN_SCAN = [
    ("annotation.json truncated", lambda d: truncate(d / "annotation.json"), "drop", AI),
    ("Rtilt is a string", _ann(lambda a: a.__setitem__("Rtilt", "upright")), "drop", ("pose_invalid",)),
    ("Rtilt holds NaN", _ann(lambda a: a["Rtilt"][0].__setitem__(0, float("nan"))), "drop", ("pose_invalid",)),
    ("K is 2x2", _ann(lambda a: a.__setitem__("K", [[1, 0], [0, 1]])), "drop", ("intrinsics_invalid",)),
    ("width is 'wide'", _ann(lambda a: a.__setitem__("width", "wide")), "drop", AI),
    ("object center missing", _ann(lambda a: a["objects"][0].pop("center")), "drop", AI),
    ("object category is a number", _ann(lambda a: a["objects"][0].__setitem__("category", 3)), "drop", AI),
    ("objects is a string", _ann(lambda a: a.__setitem__("objects", "many")), "drop", AI),
    ("depth.png missing", lambda d: (d / "depth.png").unlink(), "drop", ("depth_missing",)),
    ("depth.png is 8-bit", lambda d: _small_png(d / "depth.png"), "drop", ("depth_unreadable",)),
    ("depth.png truncated", lambda d: truncate(d / "depth.png", 0.3), "drop", ("depth_unreadable",)),
    ("image.jpg empty", lambda d: (d / "image.jpg").write_bytes(b""), "drop", ("image_unreadable",)),
    ("depth_scale is 0", _ann(lambda a: a.__setitem__("depth_scale", 0)), "drop", AI),
    ("image name climbs out", _ann(lambda a: a.__setitem__("image", "../../../etc/passwd")), "drop",
     ("path_outside_input",)),
]
SUN_IMAGE = [
    ("annotation.json truncated", lambda d: truncate(d / "annotation.json"), "drop", AI),
    ("K is 2x2", _ann(lambda a: a.__setitem__("K", [[1, 0], [0, 1]])), "drop", AI),
    ("width is 'wide'", _ann(lambda a: a.__setitem__("width", "wide")), "drop", AI),
    ("objects is a string", _ann(lambda a: a.__setitem__("objects", "many")), "drop", AI),
    ("object bbox2d_xyxy missing", _ann(lambda a: a["objects"][0].pop("bbox2d_xyxy")), "drop", AI),
    ("image.jpg truncated", lambda d: truncate(d / "image.jpg", 0.2), "drop", ("image_undecodable",)),
]


def scannet_case(name: str, damage: Callable[[Path], None], expect: str,
                 reasons: tuple[str, ...] = ()) -> Callable[[Path], Case]:
    def make(data: Path) -> Case:
        def setup(tmp: Path):
            root = writable_copy(data / "scannet_scene0000_00", tmp / "scene")
            damage(root)
            return _shards("scan.yaml", root, tmp / "out", 3), tmp / "out"
        return Case("scannet", name, setup, expect, reasons)
    return make


def _scene(fn: Callable[[dict], None]) -> Callable[[Path], None]:
    return lambda r: edit_json(r / "scene.json", fn)


def _frame0(fn: Callable[[dict], None]) -> Callable[[Path], None]:
    return _scene(lambda s: fn(sorted(s["frames"], key=lambda f: f["image"])[0]))


def _ply_header(r: Path, old: bytes, new: bytes) -> None:
    p = r / "points_raw.ply"
    p.write_bytes(p.read_bytes().replace(old, new, 1))


SCANNET = [
    ("scene.json truncated", lambda r: truncate(r / "scene.json"), "error"),
    ("scene.json empty", lambda r: (r / "scene.json").write_bytes(b""), "error"),
    ("scene.json is a JSON list", lambda r: (r / "scene.json").write_text('[{"axis_align_matrix": 1}]'), "error"),
    ("frames is a string", _scene(lambda s: s.__setitem__("frames", "color/00000.jpg")), "error"),
    ("frames lists numbers", _scene(lambda s: s.__setitem__("frames", [1, 2])), "drop", AI),
    ("frame without image", _frame0(lambda f: f.pop("image")), "drop", AI),
    ("frame listed twice", _scene(lambda s: s["frames"].append(dict(s["frames"][0]))), "drop", AI),
    ("cam_to_world is a string", _frame0(lambda f: f.__setitem__("cam_to_world", "identity")), "drop", ("pose_invalid",)),
    ("cam_to_world is 3x3", _frame0(lambda f: f.__setitem__("cam_to_world", [[1, 0, 0], [0, 1, 0], [0, 0, 1]])), "drop",
     ("pose_invalid",)),
    ("cam_to_world holds NaN", _frame0(lambda f: f["cam_to_world"][0].__setitem__(0, float("nan"))), "drop",
     ("pose_invalid",)),
    ("K_color missing", _scene(lambda s: s.pop("K_color")), "drop", ("intrinsics_invalid",)),
    ("K_color is 2x3", _scene(lambda s: s.__setitem__("K_color", [[1, 0, 0], [0, 1, 0]])), "drop",
     ("intrinsics_invalid",)),
    ("image_size is 'big'", _scene(lambda s: s.__setitem__("image_size", "big")), "drop", ("intrinsics_invalid",)),
    ("axis_align_matrix is 3x3", _scene(lambda s: s.__setitem__("axis_align_matrix", [[1, 0, 0]] * 3)), "drop",
     ("pose_invalid",)),
    ("object aligned_box missing", _scene(lambda s: s["objects"][0].pop("aligned_box")), "drop", AI),
    ("object category missing", _scene(lambda s: s["objects"][0].pop("category")), "drop", AI),
    ("object id is a string", _scene(lambda s: s["objects"][0].__setitem__("id", "w")), "drop", AI),
    ("points_raw.ply truncated", lambda r: truncate(r / "points_raw.ply"), "drop", ("points_unreadable",)),
    ("points_raw.ply empty", lambda r: (r / "points_raw.ply").write_bytes(b""), "drop", ("points_unreadable",)),
    ("points_raw.ply claims 10^12 vertices", lambda r: _ply_header(r, b"element vertex 40684", b"element vertex 999999999999"),
     "drop", ("points_unreadable",)),
    ("points_raw.ply unknown property type", lambda r: _ply_header(r, b"property float x", b"property quad x"), "drop",
     ("points_unreadable",)),
    ("points_raw.ply header never ends", lambda r: _ply_header(r, b"end_header", b"end_head"), "drop",
     ("points_unreadable",)),
    ("colour frame truncated", lambda r: truncate(r / "color" / "00000.jpg", 0.0002), "drop", ("image_unreadable",)),
    ("colour frame missing", lambda r: (r / "color" / "00000.jpg").unlink(), "drop", ("image_missing",)),
    ("frame image climbs out", _frame0(lambda f: f.__setitem__("image", "../../../../etc/passwd")), "drop",
     ("path_outside_input",)),
]


def trajectory_case(name: str, damage: Callable[[Path], None], expect: str,
                    reasons: tuple[str, ...] = ()) -> Callable[[Path], Case]:
    def make(data: Path) -> Case:
        def setup(tmp: Path):
            root = writable_copy(data / "open3d_rgbd" / "icl_nuim_livingroom", tmp / "seq")
            damage(root)
            return _shards("scan_trajectory.yaml", root, tmp / "out", 1), tmp / "out"
        return Case("rgbd trajectory", name, setup, expect, reasons)
    return make


def _to_ppm(r: Path) -> None:
    from PIL import Image

    for p in sorted((r / "color").glob("*.jpg")):
        Image.open(p).save(p.with_suffix(".ppm"))
        p.unlink()


def _rename_ext(r: Path, ext: str) -> None:
    for p in sorted((r / "color").glob("*.jpg")):
        p.rename(p.with_suffix(ext))


TRAJECTORY = [
    ("trajectory.log truncated", lambda r: truncate(r / "trajectory.log", 0.5), "drop", ("pose_invalid",)),
    ("trajectory.log holds words", lambda r: (r / "trajectory.log").write_text("0 0 1\na b c d\n" * 5), "drop",
     ("pose_invalid",)),
    ("camera json is not JSON", lambda r: (r / "camera_primesense.json").write_text("{width: 640"), "drop",
     ("intrinsics_invalid",)),
    ("camera intrinsic_matrix has 4 numbers", lambda r: edit_json(r / "camera_primesense.json",
                                                               lambda c: c.__setitem__("intrinsic_matrix", [1, 2, 3, 4])),
     "drop", ("intrinsics_invalid",)),
    ("depth frame missing", lambda r: (r / "depth" / "00000.png").unlink(), "drop", ("depth_missing",)),
    ("depth frame is 8-bit", lambda r: _small_png(r / "depth" / "00000.png"), "drop", ("depth_unreadable",)),
    ("colour frames are .ppm (were silently ignored)", _to_ppm, "ok"),
    ("colour frames have an unknown extension", lambda r: _rename_ext(r, ".xyz"), "error"),
    ("colour folder empty", lambda r: [p.unlink() for p in (r / "color").iterdir()], "error"),
]


def root_case(name: str, recipe: str, make_input: Callable[[Path], Path]) -> Callable[[Path], Case]:
    def make(data: Path) -> Case:
        def setup(tmp: Path):
            return _shards(recipe, make_input(tmp), tmp / "out", 2), tmp / "out"
        return Case("--input", name, setup, "error")
    return make


def _mk(tmp: Path, name: str, fn: Callable[[Path], None]) -> Path:
    p = tmp / name
    fn(p)
    return p


def _loop(tmp: Path) -> Path:
    a, b = tmp / "a", tmp / "b"
    os.symlink(b, a)
    os.symlink(a, b)
    return a


ROOTS = [
    ("empty folder (image)", "image.yaml", lambda t: _mk(t, "empty", lambda p: p.mkdir())),
    ("empty folder (scan)", "scan.yaml", lambda t: _mk(t, "empty", lambda p: p.mkdir())),
    ("missing folder (image)", "image.yaml", lambda t: t / "missing"),
    ("missing folder (scan)", "scan.yaml", lambda t: t / "missing"),
    ("a file, not a folder (image)", "image.yaml", lambda t: _mk(t, "f.txt", lambda p: p.write_text("x"))),
    ("a file, not a folder (scan)", "scan.yaml", lambda t: _mk(t, "f.txt", lambda p: p.write_text("x"))),
    ("a broken symlink", "image.yaml", lambda t: _mk(t, "dangling", lambda p: os.symlink(t / "nowhere", p))),
    ("a symlink loop", "scan.yaml", _loop),
    ("a path through a file", "image.yaml", lambda t: _mk(t, "f.txt", lambda p: p.write_text("x")) / "sub"),
    ("a folder of unrelated files (image)", "image.yaml",
     lambda t: _mk(t, "junk", lambda p: (p.mkdir(), (p / "a.txt").write_text("x"), (p / "b.json").write_text("{}")))),
    ("a folder of unrelated files (scan)", "scan.yaml",
     lambda t: _mk(t, "junk", lambda p: (p.mkdir(), (p / "a.txt").write_text("x")))),
    ("/dev/null", "scan.yaml", lambda t: Path("/dev/null")),
]


def input_cases() -> list[Callable[[Path], Case]]:
    """Factories (data folder -> Case) for every broken-input case, in table order."""
    out: list[Callable[[Path], Case]] = []
    out += [coco_case(*c) for c in COCO]
    out += [panoptic_case(*c) for c in PANOPTIC]
    out += [sun_case("scan", *c) for c in SUN_SCAN]
    out += [sun_case("image", *c) for c in SUN_IMAGE]
    out += [scannet_case(*c) for c in SCANNET]
    out += [trajectory_case(*c) for c in TRAJECTORY]
    out += [root_case(*c) for c in ROOTS]
    return out
