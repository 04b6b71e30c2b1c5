"""How one Sample becomes a group of MCAP messages, and back.

Why protobuf with Foxglove's well-known schemas: Foxglove recognises `foxglove.CompressedImage`,
`foxglove.RawImage`, `foxglove.CameraCalibration`, `foxglove.FrameTransform` and `foxglove.SceneUpdate`
by schema name and shows image, depth and 3D boxes without any set-up; protobuf keeps image and depth
bytes as raw bytes (no base64 inflation), parses in C, and `SerializeToString(deterministic=True)`
gives the same bytes for the same message. Everything without a well-known schema (frame metadata,
scene graphs, QA pairs, the sample header) is a JSON message (`jsonschema` encoding) written with
`core.serialize.dumps`, so it is canonical too.

One sample = the messages sharing one `sequence` number, in this order:
  /sample (header, says how many messages the sample has), then per view v:
  /cam{v}/image, /cam{v}/depth, /cam{v}/calibration, /cam{v}/tf, /cam{v}/boxes, /cam{v}/frame,
  then /graphs and /qa.
log_time = publish_time = (sequence + 1) seconds: derived from the sequence, never the clock.
"""

from __future__ import annotations

import json
from collections.abc import Callable
from dataclasses import dataclass
from typing import Any

import numpy as np

from refspatial_gen import SCHEMA_VERSION
from refspatial_gen.core.model import Frame, QAPair, Sample, SceneGraph
from refspatial_gen.core.serialize import decode_image, dumps, encode_jpeg, encode_png

PROFILE = "refspatial-gen"
NS_PER_SAMPLE = 1_000_000_000
JSON_SCHEMA = "jsonschema"

# Colours for the 3D boxes (RGBA 0..1) by colour attribute; unknown colours are grey.
_BOX_RGBA = {
    "red": (0.85, 0.15, 0.15),
    "green": (0.15, 0.65, 0.25),
    "blue": (0.15, 0.3, 0.85),
    "yellow": (0.9, 0.8, 0.15),
    "white": (0.92, 0.92, 0.92),
    "black": (0.12, 0.12, 0.12),
    "orange": (0.95, 0.5, 0.1),
    "purple": (0.5, 0.25, 0.7),
    "brown": (0.5, 0.33, 0.18),
    "gray": (0.5, 0.5, 0.5),
    "grey": (0.5, 0.5, 0.5),
    "pink": (0.95, 0.55, 0.7),
}


def _pb():
    """Foxglove protobuf classes, imported on first use (keeps `import refspatial_gen.shards` light)."""
    from foxglove_schemas_protobuf.CameraCalibration_pb2 import CameraCalibration
    from foxglove_schemas_protobuf.CompressedImage_pb2 import CompressedImage
    from foxglove_schemas_protobuf.FrameTransform_pb2 import FrameTransform
    from foxglove_schemas_protobuf.RawImage_pb2 import RawImage
    from foxglove_schemas_protobuf.SceneUpdate_pb2 import SceneUpdate

    return {
        "foxglove.CompressedImage": CompressedImage,
        "foxglove.RawImage": RawImage,
        "foxglove.CameraCalibration": CameraCalibration,
        "foxglove.FrameTransform": FrameTransform,
        "foxglove.SceneUpdate": SceneUpdate,
    }


def protobuf_schema_data(schema_name: str) -> bytes:
    """The serialised FileDescriptorSet MCAP wants for a protobuf schema (dependencies first, fixed order)."""
    from google.protobuf.descriptor_pb2 import FileDescriptorSet

    cls = _pb()[schema_name]
    fds = FileDescriptorSet()
    seen: set[str] = set()

    def add(fd) -> None:
        if fd.name in seen:
            return
        seen.add(fd.name)
        for dep in fd.dependencies:
            add(dep)
        fd.CopyToProto(fds.file.add())

    add(cls.DESCRIPTOR.file)
    return fds.SerializeToString(deterministic=True)


def json_schema_data(title: str) -> bytes:
    return dumps({"title": title, "type": "object"})


def topic_schema(topic: str) -> tuple[str, str]:
    """(schema name, schema encoding) of a topic."""
    if topic.startswith("/cam"):
        kind = topic.rsplit("/", 1)[1]
        name = {
            "image": "foxglove.CompressedImage",
            "depth": "foxglove.RawImage",
            "calibration": "foxglove.CameraCalibration",
            "tf": "foxglove.FrameTransform",
            "boxes": "foxglove.SceneUpdate",
            "frame": "refspatial.FrameMeta",
        }[kind]
    else:
        name = {"/sample": "refspatial.SampleHeader", "/graphs": "refspatial.SceneGraphs", "/qa": "refspatial.QAPairs"}[
            topic
        ]
    return name, ("protobuf" if name.startswith("foxglove.") else JSON_SCHEMA)


def _quat(R: np.ndarray) -> tuple[float, float, float, float]:
    """Rotation matrix -> unit quaternion (x, y, z, w), w >= 0."""
    R = np.asarray(R, float)
    t = np.trace(R)
    if t > 0:
        s = np.sqrt(t + 1.0) * 2
        w, x, y, z = 0.25 * s, (R[2, 1] - R[1, 2]) / s, (R[0, 2] - R[2, 0]) / s, (R[1, 0] - R[0, 1]) / s
    elif R[0, 0] > R[1, 1] and R[0, 0] > R[2, 2]:
        s = np.sqrt(1.0 + R[0, 0] - R[1, 1] - R[2, 2]) * 2
        w, x, y, z = (R[2, 1] - R[1, 2]) / s, 0.25 * s, (R[0, 1] + R[1, 0]) / s, (R[0, 2] + R[2, 0]) / s
    elif R[1, 1] > R[2, 2]:
        s = np.sqrt(1.0 + R[1, 1] - R[0, 0] - R[2, 2]) * 2
        w, x, y, z = (R[0, 2] - R[2, 0]) / s, (R[0, 1] + R[1, 0]) / s, 0.25 * s, (R[1, 2] + R[2, 1]) / s
    else:
        s = np.sqrt(1.0 + R[2, 2] - R[0, 0] - R[1, 1]) * 2
        w, x, y, z = (R[1, 0] - R[0, 1]) / s, (R[0, 2] + R[2, 0]) / s, (R[1, 2] + R[2, 1]) / s, 0.25 * s
    q = np.array([x, y, z, w])
    q /= np.linalg.norm(q)
    if q[3] < 0:
        q = -q
    return tuple(float(v) for v in q)


def _stamp(msg, t_ns: int) -> None:
    msg.timestamp.seconds = t_ns // NS_PER_SAMPLE
    msg.timestamp.nanos = t_ns % NS_PER_SAMPLE


def _ser(msg) -> bytes:
    return msg.SerializeToString(deterministic=True)


def encode_image(rgb: np.ndarray, image_format: str) -> bytes:
    if image_format == "jpeg":
        return encode_jpeg(rgb)
    if image_format == "png":
        return encode_png(rgb)
    raise ValueError(f"image_format must be 'jpeg' or 'png', got {image_format!r}")


def _view_messages(v: int, frame: Frame, t_ns: int, image_format: str, scene: str) -> list[tuple[str, bytes]]:
    pb = _pb()
    cam = frame.camera
    fid = f"cam{v}"
    img = pb["foxglove.CompressedImage"]()
    _stamp(img, t_ns)
    img.frame_id, img.format = fid, image_format
    img.data = encode_image(frame.rgb, image_format)

    dep = pb["foxglove.RawImage"]()
    _stamp(dep, t_ns)
    depth = np.ascontiguousarray(frame.depth, dtype="<f4")
    dep.frame_id, dep.width, dep.height, dep.encoding, dep.step = (
        fid,
        depth.shape[1],
        depth.shape[0],
        "32FC1",
        depth.shape[1] * 4,
    )
    dep.data = depth.tobytes()

    cal = pb["foxglove.CameraCalibration"]()
    _stamp(cal, t_ns)
    cal.frame_id, cal.width, cal.height, cal.distortion_model = fid, cam.width, cam.height, "plumb_bob"
    cal.D.extend([0.0] * 5)
    cal.K.extend([cam.fx, 0.0, cam.cx, 0.0, cam.fy, cam.cy, 0.0, 0.0, 1.0])
    cal.R.extend([1.0, 0.0, 0.0, 0.0, 1.0, 0.0, 0.0, 0.0, 1.0])
    cal.P.extend([cam.fx, 0.0, cam.cx, 0.0, 0.0, cam.fy, cam.cy, 0.0, 0.0, 0.0, 1.0, 0.0])

    tf = pb["foxglove.FrameTransform"]()
    _stamp(tf, t_ns)
    tf.parent_frame_id, tf.child_frame_id = "world", fid
    T = cam.world_from_cam
    tf.translation.x, tf.translation.y, tf.translation.z = (float(x) for x in T[:3, 3])
    tf.rotation.x, tf.rotation.y, tf.rotation.z, tf.rotation.w = _quat(T[:3, :3])

    su = _scene_update(frame, fid, t_ns, scene)
    return [
        (f"/{fid}/image", _ser(img)),
        (f"/{fid}/depth", _ser(dep)),
        (f"/{fid}/calibration", _ser(cal)),
        (f"/{fid}/tf", _ser(tf)),
        (f"/{fid}/boxes", _ser(su)),
        (f"/{fid}/frame", dumps(frame.meta_json())),
    ]


def _scene_update(frame: Frame, fid: str, t_ns: int, scene: str):
    """The 3D boxes of one view as a SceneUpdate that replaces the previous scene's in Foxglove.

    Why: entity ids are kept across messages by the 3D panel, so ids reused between scenes, or boxes
    that live forever, pile up boxes of earlier scenes. Each update first deletes every entity older
    than itself (type ALL, timestamp = this sample's time: Foxglove deletes entities *earlier* than
    it), then adds entities with ids prefixed by the sample id and a lifetime of one sample (playback
    shows one sample per second), so scrubbing to any time shows exactly that sample's boxes.
    """
    pb = _pb()
    su = pb["foxglove.SceneUpdate"]()
    gone = su.deletions.add()
    _stamp(gone, t_ns)
    gone.type = 1  # SceneEntityDeletion.Type.ALL
    boxes = [(f"{scene}/{fid}/obj{o.id}", o.box, o.category, o.attributes.get("color"), 0.55) for o in frame.objects]
    boxes += [(f"{scene}/{fid}/surface/{s.id}", s.box, s.kind, None, 0.15) for s in frame.surfaces]
    for ent_id, box, label, colour, alpha in boxes:
        ent = su.entities.add()
        _stamp(ent, t_ns)
        ent.frame_id, ent.id, ent.frame_locked = "world", ent_id, True
        ent.lifetime.seconds = NS_PER_SAMPLE // 1_000_000_000
        kv = ent.metadata.add()
        kv.key, kv.value = "category", label
        cube = ent.cubes.add()
        cube.pose.position.x, cube.pose.position.y, cube.pose.position.z = (float(x) for x in box.center)
        q = _quat(box.rotation)
        cube.pose.orientation.x, cube.pose.orientation.y, cube.pose.orientation.z, cube.pose.orientation.w = q
        cube.size.x, cube.size.y, cube.size.z = (float(x) for x in box.size)
        r, g, b = _BOX_RGBA.get(colour or "", (0.6, 0.6, 0.6))
        cube.color.r, cube.color.g, cube.color.b, cube.color.a = r, g, b, alpha
    return su


def encode_sample(sample: Sample, seq: int, image_format: str = "jpeg") -> list[tuple[str, bytes]]:
    """A Sample -> [(topic, message bytes)] in write order (the header first)."""
    if not sample.frames:
        raise ValueError(f"sample {sample.sample_id} has no frames")
    t_ns = (seq + 1) * NS_PER_SAMPLE
    body: list[tuple[str, bytes]] = []
    for v, frame in enumerate(sample.frames):
        body += _view_messages(v, frame, t_ns, image_format, sample.sample_id)
    body.append(("/graphs", dumps({"graphs": [g.to_json() for g in sample.graphs]})))
    body.append(("/qa", dumps({"qa": [q.to_json() for q in sample.qa]})))
    header = {
        "schema_version": SCHEMA_VERSION,
        "sample_id": sample.sample_id,
        "unit_key": sample.unit_key,
        "meta": sample.meta,
        "views": len(sample.frames),
        "frame_ids": [f.frame_id for f in sample.frames],
        "qa_pairs": len(sample.qa),
        "image_format": image_format,
        "n_messages": len(body) + 1,
    }
    return [("/sample", dumps(header))] + body


@dataclass
class RawSample:
    """The undecoded messages of one sample: cheap to produce, decoded piece by piece on demand.

    Why: the streaming reader hands these to training workers, which decode pixels only when used.
    """

    seq: int
    messages: dict[str, bytes]  # topic -> message bytes

    @property
    def header(self) -> dict:
        return json.loads(self.messages["/sample"])

    @property
    def views(self) -> int:
        return int(self.header["views"])

    def frame_meta(self, v: int) -> dict:
        return json.loads(self.messages[f"/cam{v}/frame"])

    def graphs_json(self) -> list[dict]:
        return json.loads(self.messages["/graphs"])["graphs"]

    def qa_json(self) -> list[dict]:
        return json.loads(self.messages["/qa"])["qa"]

    def image_bytes(self, v: int) -> tuple[bytes, str]:
        """(encoded image bytes, format) of view v, without decoding the pixels."""
        img = _pb()["foxglove.CompressedImage"]()
        img.ParseFromString(self.messages[f"/cam{v}/image"])
        return img.data, img.format

    def rgb(self, v: int) -> np.ndarray:
        return decode_image(self.image_bytes(v)[0])

    def depth(self, v: int) -> np.ndarray:
        dep = _pb()["foxglove.RawImage"]()
        dep.ParseFromString(self.messages[f"/cam{v}/depth"])
        if dep.encoding != "32FC1" or len(dep.data) != dep.width * dep.height * 4:
            raise ValueError(
                f"depth of view {v} is {dep.encoding} with {len(dep.data)} bytes for {dep.width}x{dep.height}"
            )
        return np.frombuffer(dep.data, dtype="<f4").reshape(dep.height, dep.width).copy()

    def meta(self) -> dict:
        """Everything but pixels: header, frame metadata, graphs and QA pairs as JSON."""
        h = self.header
        return {
            "seq": self.seq,
            "sample_id": h["sample_id"],
            "unit_key": h["unit_key"],
            "meta": h["meta"],
            "frames": [self.frame_meta(v) for v in range(int(h["views"]))],
            "graphs": self.graphs_json(),
            "qa": self.qa_json(),
        }

    def decode(self) -> Sample:
        h = self.header
        frames = [Frame.from_meta_json(self.frame_meta(v), self.rgb(v), self.depth(v)) for v in range(int(h["views"]))]
        return Sample(
            sample_id=h["sample_id"],
            frames=frames,
            graphs=[SceneGraph.from_json(g) for g in self.graphs_json()],
            qa=[QAPair.from_json(q) for q in self.qa_json()],
            unit_key=h["unit_key"],
            meta=dict(h["meta"]),
        )


def is_complete(messages: dict[str, bytes]) -> bool:
    """True when the header arrived and so did every message it announces."""
    if "/sample" not in messages:
        return False
    try:
        n = int(json.loads(messages["/sample"])["n_messages"])
    except (ValueError, KeyError, TypeError):
        return False
    return len(messages) == n


Decoder = Callable[[RawSample], Any]
