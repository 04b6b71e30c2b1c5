"""Scans: an unannotated office chair in front of the ScanNet desk must not become part of "the desk", and
no free-space answer may land on it.

The chair (scene0000_00, frame 00011) has no box; its back and seat lie inside the desk's box and its
base stands on the floor in front. Fixture: the chair's pixels, marked by hand in the 640x478 frame.
- With per-point instance labels (real ScanNet: segs + aggregation files, or a vertex property), the
  desk's mask keeps only pixels showing the desk's own instance. The shared sample has no labels: the
  tests build a labelled copy in tmp_path from the shared points (never committed).
- Without labels, the unexplained points standing on the floor (the chair's base) make a footprint where
  the floor gets unknown depth, so no free-space point lands between the chair's legs.
"""

from __future__ import annotations

import json
import shutil
from pathlib import Path

import numpy as np
import pytest

SCENE = "scannet_scene0000_00"
# back, armrest, seat and the hull of the five leg tips of the base
CHAIR_00011 = [(252, 178), (293, 172), (310, 135), (500, 122), (495, 205), (470, 300), (447, 352), (428, 437),
               (300, 437), (272, 352), (296, 305), (262, 290)]
REPO = Path(__file__).resolve().parents[1]


def _chair_mask(shape=(478, 640)) -> np.ndarray:
    import cv2

    m = np.zeros(shape, np.uint8)
    cv2.fillPoly(m, [np.array(CHAIR_00011, np.int32)], 1)
    return m.astype(bool)


def _labelled_copy(src: Path, dst: Path, how: str) -> None:
    """The shared scene with per-point instances: each point is the instance of the smallest box holding
    it, except the chair's points (in the hand-marked pixels of frame 00011, above the floor, below the
    chair's top and in front of the desk's back 20 cm), which are one instance without a box."""
    from refspatial_gen.sources.scan.readers.common import box_from_json, read_ply_xyz
    from refspatial_gen.sources.scan.source import load_frame

    shutil.copytree(src / "color", dst / "color")
    meta = json.loads((src / "scene.json").read_text())
    xyz_raw, rgb = read_ply_xyz(src / "points_raw.ply")
    A = np.asarray(meta["axis_align_matrix"], float)
    pts = xyz_raw @ A[:3, :3].T + A[:3, 3]
    boxes = [(int(o["id"]) + 1, box_from_json(o["aligned_box"])) for o in meta["objects"]]
    inst = np.zeros(len(pts), np.int64)
    for oid, b in sorted(boxes, key=lambda x: -x[1].volume):  # smallest box last: it wins
        inst[b.contains(pts, 0.02)] = oid
    cam = load_frame(src, "00011").camera
    uv, z = cam.project(pts)
    chair = _chair_mask()
    ok = (z > 0) & (uv[:, 0] >= 0) & (uv[:, 0] < 640) & (uv[:, 1] >= 0) & (uv[:, 1] < 478)
    on = np.zeros(len(pts), bool)
    on[ok] = chair[np.floor(uv[ok, 1]).astype(int), np.floor(uv[ok, 0]).astype(int)]
    floor_z = float(np.percentile(pts[:, 2], 2))
    desk = next(b for oid, b in boxes if meta["objects"][oid - 1]["category"] == "desk")
    back = desk.center[1] - desk.size[1] / 2 + 0.2  # the desk's back panel and the wall lie behind this
    is_chair = on & (pts[:, 2] > floor_z + 0.02) & (pts[:, 2] < 1.08) & (pts[:, 1] > back)
    inst[is_chair] = 100
    dst.mkdir(parents=True, exist_ok=True)
    if how == "vertex":
        rec = np.zeros(len(pts), dtype=[("x", "<f4"), ("y", "<f4"), ("z", "<f4"), ("red", "u1"), ("green", "u1"),
                                        ("blue", "u1"), ("instance", "<i4")])
        for k, c in enumerate("xyz"):
            rec[c] = xyz_raw[:, k]
        rec["red"], rec["green"], rec["blue"] = rgb[:, 0], rgb[:, 1], rgb[:, 2]
        rec["instance"] = inst
        header = (f"ply\nformat binary_little_endian 1.0\nelement vertex {len(pts)}\nproperty float x\n"
                  "property float y\nproperty float z\nproperty uchar red\nproperty uchar green\nproperty uchar blue\n"
                  "property int instance\nend_header\n").encode()
        (dst / "points_raw.ply").write_bytes(header + rec.tobytes())
    else:  # ScanNet's own files: one segment per instance here
        shutil.copy(src / "points_raw.ply", dst / "points_raw.ply")
        (dst / f"{SCENE}_vh_clean_2.0.010000.segs.json").write_text(json.dumps({"segIndices": inst.tolist()}))
        groups = [{"id": k, "objectId": int(i) - 1, "segments": [int(i)], "label": "chair" if i == 100 else "thing"}
                  for k, i in enumerate(sorted(set(inst.tolist()) - {0}))]
        (dst / f"{SCENE}.aggregation.json").write_text(json.dumps({"segGroups": groups}))
    (dst / "scene.json").write_text(json.dumps(meta))


def _answer_points(out: Path, frame_suffix: str) -> list[tuple[str, float, float]]:
    """(family, x, y) pixel of every answer point (points and free-space regions) on that frame."""
    import glob

    from refspatial_gen.shards.reader import read_sample_meta

    pts = []
    for shard in sorted(glob.glob(str(out / "shard-*.mcap"))):
        for s in read_sample_meta(shard):
            for q in s["qa"]:
                if not q["frame_ids"][0].endswith(frame_suffix):
                    continue
                a = q.get("answer_struct") or {}
                if a.get("kind") in ("points", "region"):
                    for x, y in a.get("points", []):
                        pts.append((q["family"], x * 640, y * 478))
    return pts


def _shards(inp: Path, out: Path, seed: int) -> None:
    from refspatial_gen.cli import main

    rc = main(["shards", "--recipe", str(REPO / "recipes" / "scan.yaml"), "--input", str(inp), "--out", str(out),
               "--seed", str(seed), "--workers", "1", "--no-report", "--quiet", "--fresh"])
    assert rc == 0


@pytest.mark.parametrize("how", ["vertex", "scannet_files"])
def test_instance_labels_keep_the_chair_out_of_the_desk(shared_data, tmp_path, how):
    from refspatial_gen.sources.scan.source import load_frame

    root = tmp_path / SCENE
    _labelled_copy(shared_data / SCENE, root, how)
    plain = load_frame(shared_data / SCENE, "00011")
    labelled = load_frame(root, "00011")
    chair = _chair_mask()
    desk0 = next(o for o in plain.objects if o.category == "desk")
    desk1 = next(o for o in labelled.objects if o.category == "desk")
    before = int((desk0.mask.decode() & chair).sum())
    after = int((desk1.mask.decode() & chair).sum())
    print(f"desk pixels on the chair: {before} without labels, {after} with ({labelled.meta['instance_labels']})")
    assert before > 10000  # the defect: the chair's back is "the desk"
    assert after < 0.2 * before  # what is left shows the desk under the armrest
    assert desk1.provenance["pixels_of_other_instances"] > 10000
    assert labelled.meta["unexplained_floor_pixels"] > 0  # the chair is a labelled thing without a box


@pytest.mark.slow
def test_labelled_scan_answers_stay_off_the_chair(shared_data, tmp_path):
    """Every answer point and free-space point of frame 00011 stays off the chair (two seeds)."""
    root = tmp_path / SCENE
    _labelled_copy(shared_data / SCENE, root, "vertex")
    chair = _chair_mask()
    for seed in (0, 1):
        out = tmp_path / f"out{seed}"
        _shards(root, out, seed)
        for fam, x, y in _answer_points(out, "00011"):
            assert not chair[int(y), int(x)], (fam, x, y)


def test_no_free_floor_between_the_legs_of_an_unannotated_chair(shared_data):
    """No labels: the floor under the chair's base gets unknown depth (no free space can be claimed)."""
    from refspatial_gen.sources.scan.source import load_frame

    f = load_frame(shared_data / SCENE, "00011")
    g = load_frame(shared_data / SCENE, "00011", {"withhold_unexplained_floor": False})
    withheld = (g.depth > 0) & (f.depth == 0)
    assert (withheld & _chair_mask()).sum() > 2000  # the floor between the chair's legs
    assert f.meta["unexplained_floor_pixels"] == int(withheld.sum())
    assert [o.category for o in f.objects] == [o.category for o in g.objects]  # masks are unchanged


@pytest.mark.slow
def test_no_free_space_on_an_unannotated_chair(shared_data, tmp_path):
    """No labels: no free-space point of the frame lands on the chair (before: between its legs, e.g. at
    (351, 399)). Without labels the chair's back and armrest stay in the desk's mask (they lie inside
    the desk's box and touch the desk in this 40k-point cloud), so a point answering "the desk" may
    still land on the armrest: a known limit (docs/scan.md); with labels it does not (test above)."""
    chair = _chair_mask()
    points = []
    for seed in (0, 1, 2):
        out = tmp_path / f"out{seed}"
        _shards(shared_data / SCENE, out, seed)
        points += _answer_points(out, "00011")
    free = [(x, y) for fam, x, y in points if fam == "placement"]
    assert free
    on_chair = [(x, y) for x, y in free if chair[int(y), int(x)]]
    assert not on_chair, on_chair
