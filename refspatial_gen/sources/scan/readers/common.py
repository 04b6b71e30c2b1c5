"""Helpers shared by readers: box lists in the generic schema, intrinsics conventions, PLY and pose parsing."""

from __future__ import annotations

import json
from pathlib import Path
from typing import Any

import numpy as np

from refspatial_gen.core.camera import Camera
from refspatial_gen.core.errors import DropUnit
from refspatial_gen.core.geometry import Box3D, rot_z
from refspatial_gen.sources.scan.view import ScanBox


def camera_from_K(K, width: int, height: int, world_from_cam, pixel_origin: str = "center",
                  gravity_known: bool = True) -> Camera:
    """Build a Camera from a 3x3 K. `pixel_origin="center"` is the OpenCV convention (pixel centres at
    integers, as in SUN RGB-D's 0-based K, ScanNet, Open3D, TUM); Camera uses corner origin (pixel i spans
    [i, i+1)), so such K get cx, cy + 0.5. COLMAP and MuJoCo already use the corner origin."""
    K = np.asarray(K, float).reshape(3, 3)
    off = 0.5 if pixel_origin == "center" else 0.0
    if pixel_origin not in ("center", "corner"):
        raise ValueError(f"pixel_origin must be 'center' or 'corner', got {pixel_origin!r}")
    return Camera(int(width), int(height), K[0, 0], K[1, 1], K[0, 2] + off, K[1, 2] + off,
                  np.asarray(world_from_cam, float), gravity_known)


def box_from_json(d: dict[str, Any]) -> Box3D:
    """{center, size, yaw} or {center, size, rotation 3x3} -> Box3D."""
    if "rotation" in d and d["rotation"] is not None:
        return Box3D(np.array(d["center"], float), np.array(d["size"], float), np.array(d["rotation"], float))
    return Box3D(np.array(d["center"], float), np.array(d["size"], float), rot_z(float(d.get("yaw", 0.0))))


def parse_objects(items: list[dict[str, Any]], where: str) -> list[ScanBox]:
    """Objects in the generic schema: id (> 0), category, center, size, yaw|rotation, optional front,
    front_phrase, name, attributes. Malformed entries drop the unit: the annotation is unusable."""
    out = []
    seen = set()
    for k, o in enumerate(items):
        try:
            oid = int(o.get("id", k + 1))
            box = box_from_json(o)
            front = None if o.get("front") is None else np.array(o["front"], float)
            cat = str(o["category"])
        except (KeyError, TypeError, ValueError) as e:
            raise DropUnit("annotation_invalid", f"{where}: object {k}: {e}") from e
        if oid <= 0 or oid in seen:
            raise DropUnit("annotation_invalid", f"{where}: object ids must be unique and > 0, got {oid}")
        seen.add(oid)
        if front is not None:
            front = front / np.linalg.norm(front)
        out.append(ScanBox(oid, cat, box, front, o.get("front_phrase"), o.get("name"),
                           {str(a): str(b) for a, b in sorted((o.get("attributes") or {}).items())},
                           {"annotation": where}))
    return out


def load_box_file(path: Path) -> list[ScanBox]:
    """A side file of boxes: {"objects": [...]} or a bare list, in the scan's world frame."""
    try:
        data = json.loads(Path(path).read_text())
    except (OSError, json.JSONDecodeError) as e:
        raise DropUnit("annotation_invalid", f"{path}: {e}") from e
    items = data.get("objects", []) if isinstance(data, dict) else data
    return parse_objects(items, str(Path(path).name))


def read_json(path: Path) -> Any:
    try:
        return json.loads(Path(path).read_text())
    except (OSError, json.JSONDecodeError) as e:
        raise DropUnit("annotation_invalid", f"{path}: {e}") from e


def read_ply_xyz(path: Path) -> tuple[np.ndarray, np.ndarray | None]:
    """Binary little-endian or ASCII PLY vertices -> (xyz float64 (N,3), rgb uint8 (N,3) or None)."""
    types = {"float": "<f4", "float32": "<f4", "double": "<f8", "float64": "<f8", "uchar": "u1", "uint8": "u1",
             "char": "i1", "int8": "i1", "ushort": "<u2", "uint16": "<u2", "short": "<i2", "int16": "<i2",
             "int": "<i4", "int32": "<i4", "uint": "<u4", "uint32": "<u4"}
    raw = Path(path).read_bytes()
    end = raw.find(b"end_header")
    if end < 0:
        raise DropUnit("points_unreadable", f"{path}: no PLY header")
    body_start = raw.index(b"\n", end) + 1
    header = raw[:end].decode("ascii", "replace").splitlines()
    fmt, n, props, in_vertex = "", 0, [], False
    for line in header:
        parts = line.split()
        if not parts:
            continue
        if parts[0] == "format":
            fmt = parts[1]
        elif parts[0] == "element":
            in_vertex = parts[1] == "vertex"
            if in_vertex:
                n = int(parts[2])
        elif parts[0] == "property" and in_vertex:
            if parts[1] == "list":
                raise DropUnit("points_unreadable", f"{path}: list properties on vertices are not supported")
            props.append((parts[2], types[parts[1]]))
    names = [p[0] for p in props]
    if fmt == "binary_little_endian":
        arr = np.frombuffer(raw, dtype=np.dtype(props), count=n, offset=body_start)
        cols = {k: arr[k] for k in names}
    elif fmt == "ascii":
        txt = np.loadtxt(raw[body_start:].decode().splitlines()[:n], ndmin=2)
        cols = {k: txt[:, i] for i, k in enumerate(names)}
    else:
        raise DropUnit("points_unreadable", f"{path}: PLY format {fmt!r} not supported")
    xyz = np.stack([cols["x"], cols["y"], cols["z"]], axis=1).astype(np.float64)
    rgb = None
    if all(c in cols for c in ("red", "green", "blue")):
        rgb = np.stack([cols["red"], cols["green"], cols["blue"]], axis=1).astype(np.uint8)
    return xyz, rgb


def to_h(T) -> np.ndarray:
    """3x4 or 4x4 list -> 4x4 float array."""
    A = np.asarray(T, float)
    if A.shape == (3, 4):
        A = np.vstack([A, [0, 0, 0, 1.0]])
    if A.shape != (4, 4):
        raise DropUnit("pose_invalid", f"pose has shape {A.shape}")
    return A
