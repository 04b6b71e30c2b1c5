"""MCAP recordings of RGB-D streams with Foxglove schemas (protobuf or JSON message encoding).

Channels are recognised by schema name:
  * colour: `foxglove.CompressedImage` (jpeg/png) or `foxglove.RawImage` (rgb8/bgr8/rgba8/bgra8/mono8);
  * depth: `foxglove.RawImage` with encoding 16UC1 (mm) or 32FC1 (metres), matched by time;
  * intrinsics: `foxglove.CameraCalibration` for the image's frame_id (K row-major, OpenCV pixel centres);
  * poses: `foxglove.FrameTransform(s)`, parent = the world frame, child = the image's frame_id
    (the child's pose in the parent frame, i.e. world_from_cam, optical axes x right, y down, z forward);
  * boxes: `foxglove.SceneUpdate` cubes in the world frame, category from the entity metadata key
    "category" (else the entity id), annotation id from metadata "id" (else sorted order + 1);
    or a side file (`boxes_file` in the recipe, or `<recording>.boxes.json`).
Which colour topic, which world frame, the time tolerance and an `up` vector come from the recipe's
`options` (`color_topic`, `depth_topic`, `world_frame` "world", `max_dt` 0.05 s, `up`); with no `up`
the floor plane is fitted. Views are the colour messages, "<topic>/<log_time ns>".
"""

from __future__ import annotations

import base64
import json
from functools import lru_cache
from pathlib import Path
from typing import Any

import numpy as np

from refspatial_gen.core.errors import DropUnit
from refspatial_gen.core.geometry import Box3D
from refspatial_gen.sources.scan.readers.common import camera_from_K, load_box_file
from refspatial_gen.sources.scan.readers.leveling import level_views
from refspatial_gen.sources.scan.view import ScanBox, ScanView

COLOR_SCHEMAS = ("foxglove.CompressedImage", "foxglove.RawImage")


def quat_to_R(q: dict[str, float]) -> np.ndarray:
    x, y, z, w = (float(q.get(k, 0.0)) for k in ("x", "y", "z", "w"))
    n = np.sqrt(x * x + y * y + z * z + w * w)
    if n < 1e-12:
        raise DropUnit("pose_invalid", "zero quaternion")
    x, y, z, w = x / n, y / n, z / n, w / n
    return np.array(
        [
            [1 - 2 * (y * y + z * z), 2 * (x * y - z * w), 2 * (x * z + y * w)],
            [2 * (x * y + z * w), 1 - 2 * (x * x + z * z), 2 * (y * z - x * w)],
            [2 * (x * z - y * w), 2 * (y * z + x * w), 1 - 2 * (x * x + y * y)],
        ]
    )


def _pb_class(schema_name: str):
    import importlib

    short = schema_name.split(".")[-1]
    return getattr(importlib.import_module(f"foxglove_schemas_protobuf.{short}_pb2"), short)


def decode_message(schema_name: str, encoding: str, data: bytes) -> dict[str, Any]:
    """A Foxglove message (protobuf or JSON) -> plain dict with field names as in the schema; bytes stay bytes."""
    if encoding == "json":
        try:
            d = json.loads(data)
            if not isinstance(d, dict):
                raise ValueError("not a JSON object")
            if isinstance(d.get("data"), str):
                d["data"] = base64.b64decode(d["data"])
        except (ValueError, TypeError, RecursionError) as e:  # JSONDecodeError, binascii.Error
            raise DropUnit("message_undecodable", f"{schema_name} JSON message: {type(e).__name__}") from None
        return d
    if encoding == "protobuf":
        from google.protobuf.json_format import MessageToDict
        from google.protobuf.message import DecodeError

        try:
            msg = _pb_class(schema_name).FromString(data)
        except (DecodeError, ValueError, TypeError) as e:
            raise DropUnit("message_undecodable", f"{schema_name}: {e}") from None
        except (ImportError, AttributeError):
            raise DropUnit("message_undecodable", f"unknown schema {schema_name!r}") from None
        d = MessageToDict(msg, preserving_proto_field_name=True)
        if hasattr(msg, "data") and isinstance(msg.data, bytes):
            d["data"] = bytes(msg.data)
        return d
    raise DropUnit("message_undecodable", f"message encoding {encoding!r} not supported")


@lru_cache(maxsize=4)
def _index(path: str) -> dict[str, Any]:
    """Every message's (topic, schema, encoding, log_time) plus decoded small messages (calibration, poses, boxes)."""
    from mcap.reader import make_reader

    topics: dict[str, tuple[str, str]] = {}
    times: dict[str, list[int]] = {}
    small: dict[str, list[tuple[int, dict[str, Any]]]] = {"calib": [], "tf": [], "scene": []}
    with open(path, "rb") as f:
        try:
            it = make_reader(f).iter_messages(log_time_order=True)
            first = [next(it, None)]
        except Exception as e:  # the mcap library raises several exception types for damaged files
            raise DropUnit("recording_unreadable", f"{path}: {type(e).__name__}: {e}") from e
        for schema, channel, msg in (m for src in (first, it) for m in src if m is not None):
            name = schema.name if schema is not None else ""
            topics[channel.topic] = (name, channel.message_encoding)
            times.setdefault(channel.topic, []).append(int(msg.log_time))
            kind = {
                "foxglove.CameraCalibration": "calib",
                "foxglove.FrameTransform": "tf",
                "foxglove.FrameTransforms": "tf",
                "foxglove.SceneUpdate": "scene",
            }.get(name)
            if kind:
                d = decode_message(name, channel.message_encoding, msg.data)
                for t in d.get("transforms", [d]) if name == "foxglove.FrameTransforms" else [d]:
                    small[kind].append((int(msg.log_time), t))
    return {"topics": topics, "times": {k: sorted(v) for k, v in times.items()}, **small}


def _message_at(path: str, topic: str, t: int) -> dict[str, Any]:
    from mcap.reader import make_reader

    with open(path, "rb") as f:
        for schema, channel, msg in make_reader(f).iter_messages(topics=[topic], starting_at=t, ending_at=t):
            if msg.log_time == t:
                return decode_message(schema.name, channel.message_encoding, msg.data)
    raise DropUnit("message_missing", f"{path}: no {topic} message at {t}")


def decode_image_message(d: dict[str, Any], schema: str) -> np.ndarray:
    """Colour message -> uint8 RGB."""
    from refspatial_gen.core.serialize import decode_image

    data = d.get("data", b"")
    if schema == "foxglove.CompressedImage":
        try:
            return decode_image(bytes(data))
        except ValueError as e:
            raise DropUnit("image_unreadable", f"compressed image ({d.get('format')}) could not be decoded") from e
    w, h, enc = int(d.get("width", 0)), int(d.get("height", 0)), str(d.get("encoding", ""))
    ch = {"rgb8": 3, "bgr8": 3, "rgba8": 4, "bgra8": 4, "mono8": 1}.get(enc)
    step = int(d.get("step", w * (ch or 1)))
    if ch is None or len(data) < step * h or w * h == 0:
        raise DropUnit("image_unreadable", f"raw image {w}x{h} {enc!r} with {len(data)} bytes")
    a = np.frombuffer(data, np.uint8)[: step * h].reshape(h, step)[:, : w * ch].reshape(h, w, ch)
    if enc.startswith("bgr"):
        a = a[..., [2, 1, 0]]
    elif enc == "mono8":
        a = np.repeat(a, 3, axis=2)
    return np.ascontiguousarray(a[..., :3])


def decode_depth_message(d: dict[str, Any]) -> np.ndarray:
    w, h, enc = int(d.get("width", 0)), int(d.get("height", 0)), str(d.get("encoding", ""))
    data = d.get("data", b"")
    if enc == "16UC1" and len(data) >= 2 * w * h:
        return np.frombuffer(data, "<u2")[: w * h].reshape(h, w).astype(np.float32) / 1000.0
    if enc == "32FC1" and len(data) >= 4 * w * h:
        return np.frombuffer(data, "<f4")[: w * h].reshape(h, w).astype(np.float32).copy()
    raise DropUnit("depth_unreadable", f"depth image {w}x{h} {enc!r} with {len(data)} bytes")


def _stamp_ok(t_msg: int, t: int, max_dt_ns: int) -> bool:
    return abs(t_msg - t) <= max_dt_ns


class McapReader:
    name = "mcap"

    def _files(self, root: Path) -> list[Path]:
        root = Path(root)
        if root.is_file() and root.suffix == ".mcap":
            return [root]
        return sorted(root.glob("*.mcap")) if root.is_dir() else []

    def detect(self, root: Path) -> bool:
        return bool(self._files(root))

    def _color_topic(self, idx: dict[str, Any], config: dict[str, Any]) -> str:
        opts = config.get("options") or {}
        if opts.get("color_topic"):
            return str(opts["color_topic"])
        cands = sorted(t for t, (s, _) in idx["topics"].items() if s in COLOR_SCHEMAS and "depth" not in t.lower())
        if not cands:
            raise DropUnit("recording_invalid", "no colour image topic")
        return cands[0]

    def _depth_topic(self, idx: dict[str, Any], config: dict[str, Any]) -> str | None:
        opts = config.get("options") or {}
        if opts.get("depth_topic"):
            return str(opts["depth_topic"])
        cands = sorted(t for t, (s, _) in idx["topics"].items() if s == "foxglove.RawImage" and "depth" in t.lower())
        return cands[0] if cands else None

    def views(self, root: Path, config: dict[str, Any]) -> list[str]:
        out = []
        for f in self._files(root):
            idx = _index(str(f.resolve()))
            topic = self._color_topic(idx, config)
            out += [f"{f.name}:{topic}/{t:020d}" for t in idx["times"][topic]]
        return sorted(out)

    def read(self, root: Path, view_id: str, config: dict[str, Any]) -> ScanView:
        root = Path(root)
        fname, rest = view_id.split(":", 1)
        topic, ts = rest.rsplit("/", 1)
        t = int(ts)
        path = str(((root / fname) if root.is_dir() else root).resolve())
        idx = _index(path)
        opts = config.get("options") or {}
        max_dt = int(float(opts.get("max_dt", 0.05)) * 1e9)
        world = str(opts.get("world_frame", "world"))
        schema = idx["topics"][topic][0]
        img_msg = _message_at(path, topic, t)
        rgb = decode_image_message(img_msg, schema)
        frame_id = str(img_msg.get("frame_id", ""))
        dtopic = self._depth_topic(idx, config)
        if dtopic is None:
            raise DropUnit("depth_missing", "recording has no depth topic")
        dts = [x for x in idx["times"].get(dtopic, []) if _stamp_ok(x, t, max_dt)]
        if not dts:
            raise DropUnit("depth_missing", f"no depth message within {max_dt / 1e9:.3f} s of {t}")
        depth = decode_depth_message(_message_at(path, dtopic, min(dts, key=lambda x: (abs(x - t), x))))
        calib = [d for tt, d in idx["calib"] if d.get("frame_id", "") == frame_id and tt <= t + max_dt]
        if not calib:
            raise DropUnit("intrinsics_missing", f"no CameraCalibration for frame {frame_id!r}")
        c = calib[-1]
        K = np.array(c["K"], float).reshape(3, 3)
        tfs = [
            (tt, d) for tt, d in idx["tf"] if d.get("child_frame_id") == frame_id and d.get("parent_frame_id") == world
        ]
        near = [(abs(tt - t), tt, d) for tt, d in tfs if _stamp_ok(tt, t, max_dt)]
        if not near:
            raise DropUnit("pose_missing", f"no {world}->{frame_id} transform within {max_dt / 1e9:.3f} s of {t}")
        tf = min(near, key=lambda x: (x[0], x[1]))[2]
        T = np.eye(4)
        T[:3, :3] = quat_to_R(tf.get("rotation", {}))
        tr = tf.get("translation", {})
        T[:3, 3] = [float(tr.get(k, 0.0)) for k in ("x", "y", "z")]
        cam = camera_from_K(K, int(c["width"]), int(c["height"]), T, "center", gravity_known=False)
        boxes = self._boxes(path, idx, world, t, config)
        view = ScanView(
            "mcap",
            Path(path).stem,
            view_id.replace(":", "_"),
            rgb,
            depth,
            cam,
            boxes,
            "unknown",
            meta={
                "intrinsics_source": "CameraCalibration",
                "pose_source": "FrameTransform",
                "color_topic": topic,
                "depth_topic": dtopic,
            },
        )
        up = opts.get("up")
        return level_views(
            view,
            None if up is None else np.asarray(up, float),
            lambda: (
                cam.depth_to_points(depth, stride=8)
                if depth.shape == (cam.height, cam.width) and np.all(np.isfinite(depth))
                else np.zeros((0, 3)),
                cam.world_from_cam[:3, :3] @ np.array([0.0, -1.0, 0.0]),
            ),
        )

    def _boxes(self, path: str, idx: dict[str, Any], world: str, t: int, config: dict[str, Any]) -> list[ScanBox]:
        side = config.get("boxes_file") or (
            Path(path).with_suffix(".boxes.json") if Path(path).with_suffix(".boxes.json").is_file() else None
        )
        if side:
            return load_box_file(Path(side))
        updates = [d for tt, d in idx["scene"] if tt <= t]
        entities: dict[str, dict[str, Any]] = {}
        for u in updates:  # later updates replace earlier entities with the same id
            for dl in u.get("deletions", []):
                if dl.get("type", "MATCHING_ID") in ("MATCHING_ID", 0):
                    entities.pop(str(dl.get("id", "")), None)
                else:
                    entities.clear()
            for e in u.get("entities", []):
                entities[str(e.get("id", ""))] = e
        boxes = []
        for k, eid in enumerate(sorted(entities)):
            e = entities[eid]
            if e.get("frame_id", world) != world or not e.get("cubes"):
                continue
            meta = {m.get("key"): m.get("value") for m in e.get("metadata", [])}
            cube = e["cubes"][0]
            pose = cube.get("pose", {})
            pos = pose.get("position", {})
            size = cube.get("size", {})
            try:
                box = Box3D(
                    np.array([float(pos.get(a, 0.0)) for a in "xyz"]),
                    np.array([float(size.get(a, 0.0)) for a in "xyz"]),
                    quat_to_R(pose.get("orientation", {"w": 1.0})),
                )
                oid = int(meta.get("id", k + 1))
            except ValueError as ex:
                raise DropUnit("annotation_invalid", f"scene entity {eid}: {ex}") from ex
            boxes.append(
                ScanBox(
                    oid,
                    str(meta.get("category", eid.rstrip("0123456789_-"))),
                    box,
                    provenance={"annotation": "SceneUpdate", "entity_id": eid},
                )
            )
        return boxes
