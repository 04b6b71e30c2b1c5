"""Helpers shared by readers: box lists in the generic schema, intrinsics conventions, PLY and pose parsing."""

from __future__ import annotations

import json
from pathlib import Path
from typing import Any

import numpy as np

from refspatial_gen.core.camera import Camera
from refspatial_gen.core.errors import DropUnit
from refspatial_gen.core.geometry import Box3D, rot_z
from refspatial_gen.sources.scan.readers import validate as V
from refspatial_gen.sources.scan.view import ScanBox


def camera_from_K(
    K, width: int, height: int, world_from_cam, pixel_origin: str = "center", gravity_known: bool = True
) -> Camera:
    """Build a Camera from a 3x3 K. `pixel_origin="center"` is the OpenCV convention (pixel centres at
    integers, as in SUN RGB-D's 0-based K, ScanNet, Open3D, TUM); Camera uses corner origin (pixel i spans
    [i, i+1)), so such K get cx, cy + 0.5. COLMAP and MuJoCo already use the corner origin."""
    K = V.matrix(K, ((3, 3),), "K", "intrinsics_invalid")
    if K[0, 0] <= 0 or K[1, 1] <= 0:
        raise DropUnit("intrinsics_invalid", f"focal lengths must be > 0, got {K[0, 0]}, {K[1, 1]}")
    off = 0.5 if pixel_origin == "center" else 0.0
    if pixel_origin not in ("center", "corner"):
        raise DropUnit("intrinsics_invalid", f"pixel_origin must be 'center' or 'corner', got {V.short(pixel_origin)}")
    width = V.positive_int(width, "image width", "intrinsics_invalid")
    height = V.positive_int(height, "image height", "intrinsics_invalid")
    return Camera(
        width,
        height,
        K[0, 0],
        K[1, 1],
        K[0, 2] + off,
        K[1, 2] + off,
        V.pose(world_from_cam, "camera pose"),
        gravity_known,
    )


def box_from_json(d: dict[str, Any]) -> Box3D:
    """{center, size, yaw} or {center, size, rotation 3x3} -> Box3D; malformed values raise DropUnit."""
    d = V.mapping(d, "box")
    center = V.matrix(d.get("center"), ((3,),), "box center")
    size = V.matrix(d.get("size"), ((3,),), "box size")
    if np.any(size < 0):
        raise DropUnit("annotation_invalid", f"box size must be >= 0, got {size.tolist()}")
    if "rotation" in d and d["rotation"] is not None:
        R = V.matrix(d["rotation"], ((3, 3),), "box rotation")
        if not np.allclose(R.T @ R, np.eye(3), atol=1e-3):
            raise DropUnit("annotation_invalid", "box rotation is not a rotation matrix")
        return Box3D(center, size, R)
    return Box3D(center, size, rot_z(V.number(d.get("yaw", 0.0), "box yaw")))


def parse_objects(items: list[dict[str, Any]], where: str) -> list[ScanBox]:
    """Objects in the generic schema: id (> 0), category, center, size, yaw|rotation, optional front,
    front_phrase, name, attributes. Malformed entries drop the unit: the annotation is unusable."""
    out = []
    seen = set()
    items = V.listing(items, f"{where}: objects")
    for k, o in enumerate(items):
        try:
            o = V.mapping(o, "object")
            oid = o.get("id", k + 1)
            if isinstance(oid, bool) or not isinstance(oid, int):
                raise DropUnit("annotation_invalid", f"id must be an integer, got {V.short(oid)}")
            box = box_from_json(o)
            front = None if o.get("front") is None else V.matrix(o["front"], ((3,),), "front")
            cat = o.get("category")
            if not isinstance(cat, str) or not cat:
                raise DropUnit("annotation_invalid", f"category must be a name, got {V.short(cat)}")
            attrs = o.get("attributes") or {}
            if not isinstance(attrs, dict):
                raise DropUnit("annotation_invalid", "attributes must be a mapping")
            for key in ("front_phrase", "name"):
                if o.get(key) is not None and not isinstance(o[key], str):
                    raise DropUnit("annotation_invalid", f"{key} must be a string")
        except DropUnit as e:
            raise DropUnit(e.reason, f"{where}: object {k}: {e.detail}") from None
        if oid <= 0 or oid in seen:
            raise DropUnit("annotation_invalid", f"{where}: object ids must be unique and > 0, got {oid}")
        seen.add(oid)
        if front is not None:
            n = float(np.linalg.norm(front))
            if n <= 0:
                raise DropUnit("annotation_invalid", f"{where}: object {k}: front must not be a zero vector")
            front = front / n
        out.append(
            ScanBox(
                oid,
                cat,
                box,
                front,
                o.get("front_phrase"),
                o.get("name"),
                {str(a): str(b) for a, b in sorted(attrs.items(), key=lambda kv: str(kv[0]))},
                {"annotation": where},
            )
        )
    return out


def load_box_file(path: Path) -> list[ScanBox]:
    """A side file of boxes: {"objects": [...]} or a bare list, in the scan's world frame."""
    data = read_json(path)
    items = data.get("objects", []) if isinstance(data, dict) else data
    return parse_objects(items, str(Path(path).name))


def read_json(path: Path) -> Any:
    """A per-view JSON file; unreadable or malformed -> DropUnit (the view is dropped)."""
    try:
        return json.loads(Path(path).read_bytes())
    except OSError as e:
        raise DropUnit(
            "annotation_missing" if isinstance(e, FileNotFoundError) else "annotation_unreadable",
            f"{path}: {e.strerror or e}",
        ) from None
    except (ValueError, RecursionError) as e:  # JSONDecodeError, UnicodeDecodeError
        raise DropUnit("annotation_invalid", f"{path}: not valid JSON ({type(e).__name__})") from None


PLY_TYPES = {
    "float": "<f4",
    "float32": "<f4",
    "double": "<f8",
    "float64": "<f8",
    "uchar": "u1",
    "uint8": "u1",
    "char": "i1",
    "int8": "i1",
    "ushort": "<u2",
    "uint16": "<u2",
    "short": "<i2",
    "int16": "<i2",
    "int": "<i4",
    "int32": "<i4",
    "uint": "<u4",
    "uint32": "<u4",
}


def _ply_header(raw: bytes, path: Path) -> tuple[str, int, list[tuple[str, str]], int]:
    """-> (format, vertex count, vertex properties, body offset); a header that cannot be followed drops."""
    bad = lambda msg: DropUnit("points_unreadable", f"{Path(path).name}: {msg}")  # noqa: E731
    if not raw.startswith(b"ply"):
        raise bad("not a PLY file")
    end = raw.find(b"end_header")
    if end < 0:
        raise bad("no PLY header end (truncated?)")
    nl = raw.find(b"\n", end)
    if nl < 0:
        raise bad("nothing after the PLY header (truncated?)")
    fmt, n, props, in_vertex, seen_vertex = "", 0, [], False, False
    for line in raw[:end].decode("ascii", "replace").splitlines():
        parts = line.split()
        if not parts:
            continue
        if parts[0] == "format" and len(parts) >= 2:
            fmt = parts[1]
        elif parts[0] == "element" and len(parts) >= 3:
            in_vertex = parts[1] == "vertex"
            if in_vertex:
                if seen_vertex or not parts[2].isdigit():
                    raise bad(f"bad vertex element line {line.strip()[:40]!r}")
                n, seen_vertex = int(parts[2]), True
            elif not seen_vertex:
                raise bad("elements before the vertex element are not supported")
        elif parts[0] == "property" and in_vertex:
            if len(parts) >= 2 and parts[1] == "list":
                raise bad("list properties on vertices are not supported")
            if len(parts) != 3 or parts[1] not in PLY_TYPES:
                raise bad(f"bad vertex property {line.strip()[:40]!r}")
            props.append((parts[2], PLY_TYPES[parts[1]]))
    names = [p[0] for p in props]
    if not seen_vertex or not all(c in names for c in "xyz") or len(set(names)) != len(names):
        raise bad("no vertex element with x, y, z properties")
    return fmt, n, props, nl + 1


def read_ply_xyz(path: Path) -> tuple[np.ndarray, np.ndarray | None]:
    """Binary little-endian or ASCII PLY vertices -> (xyz float64 (N,3), rgb uint8 (N,3) or None).

    Every way a file can be short or malformed (a truncated body, a vertex count larger than the data,
    unknown types, non-numbers) raises DropUnit("points_unreadable"), and non-finite points are too."""
    try:
        raw = Path(path).read_bytes()
    except OSError as e:
        raise DropUnit("points_unreadable", f"{Path(path).name}: {e.strerror or e}") from None
    fmt, n, props, body = _ply_header(raw, path)
    names = [p[0] for p in props]
    if fmt == "binary_little_endian":
        dt = np.dtype(props)
        if len(raw) - body < n * dt.itemsize:
            raise DropUnit(
                "points_unreadable",
                f"{Path(path).name}: {n} vertices announced, "
                f"{(len(raw) - body) // max(dt.itemsize, 1)} present (truncated?)",
            )
        arr = np.frombuffer(raw, dtype=dt, count=n, offset=body)
        cols = {k: arr[k] for k in names}
    elif fmt == "ascii":
        rows = raw[body:].decode("ascii", "replace").splitlines()[:n]
        try:
            txt = np.array([[float(x) for x in r.split()[: len(names)]] for r in rows], float).reshape(-1, len(names))
        except ValueError:
            raise DropUnit(
                "points_unreadable", f"{Path(path).name}: a vertex line is not {len(names)} numbers"
            ) from None
        if len(txt) != n:
            raise DropUnit("points_unreadable", f"{Path(path).name}: {n} vertices announced, {len(txt)} present")
        cols = {k: txt[:, i] for i, k in enumerate(names)}
    else:
        raise DropUnit("points_unreadable", f"{Path(path).name}: PLY format {fmt!r} not supported")
    xyz = np.stack([cols["x"], cols["y"], cols["z"]], axis=1).astype(np.float64)
    if not np.all(np.isfinite(xyz)):
        raise DropUnit("points_unreadable", f"{Path(path).name}: points with NaN or infinite coordinates")
    rgb = None
    if all(c in cols for c in ("red", "green", "blue")):
        rgb = np.stack([cols["red"], cols["green"], cols["blue"]], axis=1).astype(np.uint8)
    return xyz, rgb


def to_h(T) -> np.ndarray:
    """3x4 or 4x4 list of finite numbers -> 4x4 float array (DropUnit "pose_invalid" otherwise)."""
    return V.pose(T, "pose")
