"""Generic scan format round trip (from toy frames with exact masks), bad-input drops, and MCAP recordings."""

from __future__ import annotations

import json
from pathlib import Path

import cv2
import numpy as np
import pytest

from refspatial_gen.core.errors import DropUnit
from refspatial_gen.sources import get_source
from refspatial_gen.sources.scan import load_frame
from refspatial_gen.sources.toy import TABLE, toy_frame


def write_generic(folder: Path, frames, up=(0, 0, 1), per_frame=False) -> Path:
    """Toy frames -> the generic scan format (mm PNG depth, OpenCV-convention K)."""
    (folder / "rgb").mkdir(parents=True, exist_ok=True)
    (folder / "depth").mkdir(exist_ok=True)
    cam = frames[0].camera
    objs = [{"id": o.id, "category": o.category, "center": o.box.center.tolist(), "size": o.box.size.tolist(),
             "rotation": o.box.rotation.tolist(), "attributes": o.attributes} for o in frames[0].objects]
    objs.append({"id": 99, "category": "table", "center": TABLE.center.tolist(), "size": TABLE.size.tolist(), "yaw": 0.0})
    meta = {"format": "refspatial-scan/1", "scene_id": "toyscene", "depth_encoding": "mm", "pixel_origin": "center",
            "intrinsics": {"width": cam.width, "height": cam.height, "fx": cam.fx, "fy": cam.fy,
                           "cx": cam.cx - 0.5, "cy": cam.cy - 0.5},
            "up": list(up) if up is not None else None, "boxes_per_frame": per_frame, "frames": [], "objects": objs}
    for k, f in enumerate(frames):
        cv2.imwrite(str(folder / "rgb" / f"{k:03d}.png"), f.rgb[..., ::-1])
        cv2.imwrite(str(folder / "depth" / f"{k:03d}.png"), np.round(f.depth * 1000).astype(np.uint16))
        entry = {"id": f"{k:03d}", "image": f"rgb/{k:03d}.png", "depth": f"depth/{k:03d}.png",
                 "world_from_cam": f.camera.world_from_cam.tolist()}
        if per_frame:
            entry["objects"] = objs
        meta["frames"].append(entry)
    if per_frame:
        meta["objects"] = []
    (folder / "scan.json").write_text(json.dumps(meta))
    return folder


@pytest.fixture
def toy_scan(tmp_path):
    frames = [toy_frame(np.random.default_rng(s), 5, 320, 240, frame_id=f"t{s}") for s in (3,)]
    return write_generic(tmp_path / "scan", frames), frames[0]


def test_generic_round_trip_recovers_true_masks(toy_scan):
    root, truth = toy_scan
    f = load_frame(root, "000", {"min_mask_pixels": 16, "blur_threshold": 0.0})
    assert f.meta["gravity_source"] == "given" and f.camera.gravity_known
    np.testing.assert_allclose(f.camera.world_from_cam, truth.camera.world_from_cam, atol=1e-9)
    assert abs(f.camera.cx - truth.camera.cx) < 1e-9
    got = {o.id: o for o in f.objects}
    for o in truth.objects:
        m_true = o.mask.decode()
        m = got[o.id].mask.decode()
        # masks may miss the object's bottom slab (floor margin) but must not spill off the object
        precision = (m & m_true).sum() / m.sum()
        recall = (m & m_true).sum() / m_true.sum()
        assert precision > 0.97 and recall > 0.7, (o.category, precision, recall)
        assert got[o.id].visible_fraction > 0.5
    # the table is there too, and the floor margin keeps the objects standing on it out of its mask
    table = got[99].mask.decode()
    for o in truth.objects:
        assert (table & o.mask.decode()).sum() < 0.02 * o.mask.area
    assert any(s.kind == "table" and s.object_id == 99 for s in f.surfaces)


def test_occlusion_lowers_visible_fraction(tmp_path):
    """One box hides most of another: the hidden one has a small mask and a matching visible fraction."""
    from refspatial_gen.core.camera import Camera, look_at
    from refspatial_gen.core.geometry import Box3D

    cam = Camera(320, 240, 300, 300, 160, 120, look_at(np.array([0, -1.5, 1.2]), np.array([0, 0, 0.8])))
    front = ("box", "red", Box3D(np.array([0.0, -0.2, 0.85]), np.array([0.3, 0.1, 0.2]), np.eye(3)))
    back = ("box", "blue", Box3D(np.array([0.05, 0.1, 0.9]), np.array([0.2, 0.1, 0.3]), np.eye(3)))
    truth = toy_frame(np.random.default_rng(0), boxes=[front, back], camera=cam, frame_id="occ")
    root = write_generic(tmp_path / "occ", [truth])
    f = load_frame(root, "000", {"min_mask_pixels": 1, "blur_threshold": 0.0})
    vis = {o.id: o.visible_fraction for o in f.objects}
    assert truth.object(2).mask.area > 100  # partly visible above the front box
    assert vis[1] > 0.9
    assert vis[2] < 0.6
    # unoccluded area from the toy's own rendering of the back box alone
    alone = toy_frame(np.random.default_rng(0), boxes=[back], camera=cam, frame_id="alone").object(1).mask.area
    assert abs(vis[2] - f.object(2).mask.area / alone) < 0.15


@pytest.mark.parametrize("defect,reason", [
    ("missing_pose", "pose_missing"), ("nan_pose", "pose_invalid"), ("nan_depth", "depth_nan"),
    ("zero_depth", "depth_empty"), ("box_behind", "box_behind_camera"), ("bad_image", "image_unreadable"),
    ("missing_image", "image_missing"), ("blurry", "blurry"), ("no_objects", "too_few_visible_objects"),
])
def test_bad_input_drops_only_that_frame(tmp_path, defect, reason):
    frames = [toy_frame(np.random.default_rng(s), 4, 160, 120, frame_id=f"t{s}") for s in (1, 2, 3)]
    root = write_generic(tmp_path / "bad", frames, per_frame=defect == "box_behind")
    meta = json.loads((root / "scan.json").read_text())
    bad = meta["frames"][1]
    if defect == "missing_pose":
        del bad["world_from_cam"]
    elif defect == "nan_pose":
        bad["world_from_cam"][0][3] = float("nan")
    elif defect == "nan_depth":
        np.save(root / "depth" / "001.npy", np.full((120, 160), np.nan, np.float32))
        bad["depth"] = "depth/001.npy"
        meta["depth_encoding"] = "mm"
    elif defect == "zero_depth":
        cv2.imwrite(str(root / "depth" / "001.png"), np.zeros((120, 160), np.uint16))
    elif defect == "box_behind":
        cam = frames[1].camera
        behind = cam.cam_to_world(np.array([[0.0, 0.0, -2.0]]))[0]
        bad["objects"] = bad["objects"] + [{"id": 50, "category": "ghost", "center": behind.tolist(), "size": [0.2, 0.2, 0.2], "yaw": 0.0}]
    elif defect == "bad_image":
        (root / "rgb" / "001.png").write_bytes(b"not a png at all")
    elif defect == "missing_image":
        (root / "rgb" / "001.png").unlink()
    elif defect == "blurry":
        img = cv2.imread(str(root / "rgb" / "001.png"))
        cv2.imwrite(str(root / "rgb" / "001.png"), cv2.GaussianBlur(img, (0, 0), 6))
    elif defect == "no_objects":
        bad["world_from_cam"] = np.linalg.inv(np.array([[1, 0, 0, 0], [0, 0, -1, -50.0], [0, 1, 0, 0], [0, 0, 0, 1]])).tolist()
    (root / "scan.json").write_text(json.dumps(meta))
    if defect == "nan_depth":  # an .npy depth with NaN in a frame whose encoding is metres
        pass
    src = get_source("scan")
    cfg = {k: f.default for k, f in src.CONFIG_FIELDS.items()} | {"min_mask_pixels": 16, "_input": str(root)}
    keys = src.unit_keys(cfg, None, str(root))
    assert len(keys) == 3
    with pytest.raises(DropUnit) as e:
        src.load(keys[1], np.random.default_rng(0), cfg)
    assert e.value.reason == reason, (e.value.reason, e.value.detail)
    for k in (keys[0], keys[2]):  # the other frames are unaffected
        (f,) = src.load(k, np.random.default_rng(0), cfg)
        assert f.objects


def test_unit_keys_are_deterministic_and_thinned(toy_scan):
    root, _ = toy_scan
    src = get_source("scan")
    assert src.unit_keys({}, None, str(root)) == src.unit_keys({"reader": "generic"}, None, str(root))
    with pytest.raises(ValueError):
        src.unit_keys({}, None, None)


def test_keys_and_frames_do_not_depend_on_the_folder(toy_scan, tmp_path):
    """The same scan in two folders elsewhere (one a symlink): same keys, same frames (same rng seed)."""
    import shutil

    from refspatial_gen.core.serialize import dumps
    from refspatial_gen.sources.scan import parse_unit_key

    root, _ = toy_scan
    copy = tmp_path / "moved" / "deeper" / "scan"
    shutil.copytree(root, copy)
    link = tmp_path / "link_to_scan"
    link.symlink_to(copy, target_is_directory=True)
    src = get_source("scan")
    cfg = {k: f.default for k, f in src.CONFIG_FIELDS.items()} | {"min_mask_pixels": 16}
    keys = {p: src.unit_keys(cfg, None, str(p)) for p in (root, copy, link)}
    assert keys[root] == keys[copy] == keys[link] and keys[root]
    assert all(k.startswith("scan:generic:.#") and str(tmp_path) not in k for k in keys[root])
    assert parse_unit_key(keys[root][0]) == ("generic", ".", keys[root][0].split("#")[1])
    for k in keys[root]:
        fs = [src.load(k, np.random.default_rng(11), cfg | {"_input": str(p)})[0] for p in (root, copy, link)]
        metas = [dumps(f.meta_json()) for f in fs]
        assert metas[0] == metas[1] == metas[2] and str(tmp_path).encode() not in metas[0]
        for f in fs[1:]:
            assert np.array_equal(f.rgb, fs[0].rgb) and np.array_equal(f.depth, fs[0].depth)
    # a key names no folder: load() needs `_input`, and old absolute-folder keys are refused clearly
    with pytest.raises(ValueError, match="_input"):
        src.load(keys[root][0], np.random.default_rng(11), {k: v for k, v in cfg.items() if k != "input"})
    with pytest.raises(ValueError, match="relative"):
        parse_unit_key(f"scan:generic:{root}#000")


def _write_mcap(path: Path, frames, encoding: str = "protobuf", with_boxes: bool = True) -> None:
    """A small RGB-D recording with Foxglove schemas: CompressedImage, RawImage depth, calibration,
    transforms and a SceneUpdate with one cube per object."""
    from mcap.writer import Writer

    from refspatial_gen.sources.scan.readers.mcap_reader import _pb_class

    def quat(R):
        import mujoco

        q = np.zeros(4)
        mujoco.mju_mat2Quat(q, np.ascontiguousarray(R).ravel())
        return {"w": q[0], "x": q[1], "y": q[2], "z": q[3]}

    with open(path, "wb") as fh:
        w = Writer(fh)
        w.start()
        chans = {}
        for topic, schema in [("/camera/color", "foxglove.CompressedImage"), ("/camera/depth", "foxglove.RawImage"),
                              ("/camera/calibration", "foxglove.CameraCalibration"), ("/tf", "foxglove.FrameTransform"),
                              ("/boxes", "foxglove.SceneUpdate")]:
            if encoding == "protobuf":
                from google.protobuf import descriptor_pb2

                cls = _pb_class(schema)
                fds = descriptor_pb2.FileDescriptorSet()
                seen = set()

                def add(fd):
                    if fd.name in seen:
                        return
                    for dep in fd.dependencies:
                        add(dep)
                    seen.add(fd.name)
                    p = fds.file.add()
                    fd.CopyToProto(p)

                add(cls.DESCRIPTOR.file)
                sid = w.register_schema(schema, "protobuf", fds.SerializeToString())
            else:
                sid = w.register_schema(schema, "jsonschema", b"{}")
            chans[topic] = (w.register_channel(topic, encoding, sid), schema)

        def put(topic, t, d):
            cid, schema = chans[topic]
            if encoding == "protobuf":
                from google.protobuf.json_format import ParseDict

                d2 = dict(d)
                raw = d2.pop("data", None)
                msg = ParseDict(d2, _pb_class(schema)())
                if raw is not None:
                    msg.data = raw
                data = msg.SerializeToString()
            else:
                import base64

                d2 = dict(d)
                if "data" in d2:
                    d2["data"] = base64.b64encode(d2["data"]).decode()
                data = json.dumps(d2).encode()
            w.add_message(cid, log_time=t, publish_time=t, data=data)

        t0 = 1_000_000_000
        if with_boxes:
            ents = [{"id": f"obj{o.id}", "frame_id": "world",
                     "metadata": [{"key": "category", "value": o.category}, {"key": "id", "value": str(o.id)}],
                     "cubes": [{"pose": {"position": dict(zip("xyz", o.box.center.tolist())), "orientation": quat(o.box.rotation)},
                                "size": dict(zip("xyz", o.box.size.tolist()))}]} for o in frames[0].objects]
            put("/boxes", t0 - 1, {"entities": ents})
        for k, f in enumerate(frames):
            t = t0 + k * 100_000_000
            c = f.camera
            put("/camera/calibration", t, {"frame_id": "cam", "width": c.width, "height": c.height,
                                           "K": [c.fx, 0, c.cx - 0.5, 0, c.fy, c.cy - 0.5, 0, 0, 1]})
            T = c.world_from_cam
            put("/tf", t, {"parent_frame_id": "world", "child_frame_id": "cam",
                           "translation": dict(zip("xyz", T[:3, 3].tolist())), "rotation": quat(T[:3, :3])})
            ok, png = cv2.imencode(".png", f.rgb[..., ::-1])
            put("/camera/color", t, {"frame_id": "cam", "format": "png", "data": png.tobytes()})
            dmm = np.round(f.depth * 1000).astype("<u2")
            put("/camera/depth", t + 1000, {"frame_id": "cam", "width": c.width, "height": c.height, "encoding": "16UC1",
                                            "step": c.width * 2, "data": dmm.tobytes()})
        w.finish()


@pytest.mark.parametrize("encoding", ["protobuf", "json"])
def test_mcap_recording(tmp_path, encoding):
    frames = [toy_frame(np.random.default_rng(s), 4, 160, 120, frame_id=f"m{s}") for s in (5, 6)]
    # same scene, two viewpoints: reuse scene 5's boxes with scene 6's camera
    f6 = toy_frame(np.random.default_rng(0), boxes=[(o.category, o.attributes["color"], o.box) for o in frames[0].objects],
                   camera=frames[1].camera, frame_id="m6")
    rec = tmp_path / "rec"
    rec.mkdir()
    _write_mcap(rec / "session.mcap", [frames[0], f6], encoding)
    src = get_source("scan")
    cfg = {k: f.default for k, f in src.CONFIG_FIELDS.items()} | {"min_mask_pixels": 16, "options": {"up": [0, 0, 1]},
                                                                  "_input": str(rec)}
    keys = src.unit_keys(cfg, None, str(rec))
    assert len(keys) == 2 and keys[0].startswith("scan:mcap:")
    for k, truth in zip(keys, [frames[0], f6]):
        (f,) = src.load(k, np.random.default_rng(0), cfg)
        np.testing.assert_allclose(f.camera.world_from_cam, truth.camera.world_from_cam, atol=1e-6)
        np.testing.assert_allclose(f.depth, truth.depth, atol=6e-4)
        assert {o.id for o in f.objects} == {o.id for o in truth.objects}
        for o in truth.objects:
            m, mt = f.object(o.id).mask.decode(), o.mask.decode()
            assert (m & mt).sum() / m.sum() > 0.97 and (m & mt).sum() / mt.sum() > 0.7


def test_mcap_missing_pose_drops_frame(tmp_path):
    frames = [toy_frame(np.random.default_rng(5), 4, 160, 120, frame_id="m5")]
    rec = tmp_path / "rec"
    rec.mkdir()
    _write_mcap(rec / "session.mcap", frames, "json")
    src = get_source("scan")
    cfg = {"options": {"up": [0, 0, 1], "world_frame": "map"}, "_input": str(rec)}
    (key,) = src.unit_keys(cfg, None, str(rec))
    with pytest.raises(DropUnit) as e:
        src.load(key, np.random.default_rng(0), cfg)
    assert e.value.reason == "pose_missing"
