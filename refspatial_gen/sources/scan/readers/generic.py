"""The generic scan format: a folder with scan.json, RGB frames, depth frames and oriented boxes.

    scene/
      scan.json
      rgb/000000.png ...       (any image format; paths are given per frame)
      depth/000000.png ...     (uint16 PNG in `depth_encoding`, or .npy float32 metres)

scan.json:
    {"format": "refspatial-scan/1",
     "scene_id": "kitchen_01",
     "depth_encoding": "mm",                 # mm | tum5000 | sun_shift | float_m
     "pixel_origin": "center",               # K convention: "center" (OpenCV) or "corner" (COLMAP)
     "intrinsics": {"width": 640, "height": 480, "fx": 525, "fy": 525, "cx": 319.5, "cy": 239.5},
     "up": [0, 0, 1],                        # world up vector; omit or null when unknown
     "boxes_per_frame": false,               # true: boxes annotated per frame (then listed per frame)
     "frames": [{"id": "000000", "image": "rgb/000000.png", "depth": "depth/000000.png",
                 "world_from_cam": [[...4x4...]], "intrinsics": {...optional override...},
                 "objects": [...only when boxes_per_frame...]}],
     "objects": [{"id": 1, "category": "mug", "center": [x, y, z], "size": [sx, sy, sz],
                  "yaw": 0.0 | "rotation": [[3x3]], "front": [1, 0, 0], "front_phrase": "the handle side",
                  "name": "...", "attributes": {"color": "red"}}]}

Camera poses are camera-to-world with OpenCV camera axes; metres. When `up` is given the world is
rotated so that `up` becomes +z (gravity_source "given"); when it is missing, the floor plane is
fitted over all frames (gravity_source "floor_plane"), and if none is found gravity stays unknown.
"""

from __future__ import annotations

from functools import lru_cache
from pathlib import Path
from typing import Any

import numpy as np

from refspatial_gen.core.errors import DropUnit, InputError
from refspatial_gen.sources.scan.fileio import DEPTH_ENCODINGS, read_depth, read_rgb
from refspatial_gen.sources.scan.readers import validate as V
from refspatial_gen.sources.scan.readers.common import camera_from_K, parse_objects, to_h
from refspatial_gen.sources.scan.readers.leveling import level_views
from refspatial_gen.sources.scan.view import ScanView


def _K(d: Any) -> tuple[np.ndarray, int, int]:
    d = V.mapping(d, "intrinsics", "intrinsics_invalid")
    K = np.array(
        [
            [V.number(d.get("fx"), "fx", "intrinsics_invalid"), 0, V.number(d.get("cx"), "cx", "intrinsics_invalid")],
            [0, V.number(d.get("fy"), "fy", "intrinsics_invalid"), V.number(d.get("cy"), "cy", "intrinsics_invalid")],
            [0, 0, 1.0],
        ],
        float,
    )
    return (
        K,
        V.positive_int(d.get("width"), "width", "intrinsics_invalid"),
        V.positive_int(d.get("height"), "height", "intrinsics_invalid"),
    )


def _frame_id(f: Any, k: int) -> str:
    if (
        isinstance(f, dict)
        and isinstance(f.get("id"), (str, int))
        and not isinstance(f.get("id"), bool)
        and str(f["id"])
        and not str(f["id"]).startswith("!")
        and "#" not in str(f["id"])
    ):
        return str(f["id"])
    return f"!frame{k}"


def _meta(root: Path) -> tuple[dict, list]:
    path = Path(root) / "scan.json"
    meta = V.index_json(path)
    return meta, V.view_list(meta, path)


def _encoding(meta: dict) -> str:
    enc = meta.get("depth_encoding", "mm")
    if enc not in DEPTH_ENCODINGS:
        raise DropUnit(
            "annotation_invalid",
            f"scan.json depth_encoding must be one of {', '.join(DEPTH_ENCODINGS)}, got {V.short(enc)}",
        )
    return enc


class GenericReader:
    name = "generic"

    def detect(self, root: Path) -> bool:
        p = Path(root) / "scan.json"
        try:
            return p.is_file() and "refspatial-scan/" in p.read_text(encoding="utf-8", errors="replace")[:2000]
        except OSError:
            return False

    def views(self, root: Path, config: dict[str, Any]) -> list[str]:
        _, frames = _meta(Path(root))
        return sorted({_frame_id(f, k) for k, f in enumerate(frames)})

    def read(self, root: Path, view_id: str, config: dict[str, Any]) -> ScanView:
        root = Path(root)
        try:
            meta, frames = _meta(root)
        except InputError as e:  # changed since planning
            raise DropUnit("annotation_invalid", str(e)) from None
        matches = [f for k, f in enumerate(frames) if _frame_id(f, k) == view_id]
        if not matches:
            raise DropUnit("frame_missing", f"{root}: no frame {view_id}")
        if view_id.startswith("!") or len(matches) > 1:
            raise DropUnit(
                "annotation_invalid", f"scan.json {view_id}: {'listed twice' if len(matches) > 1 else 'no usable id'}"
            )
        f = matches[0]
        if f.get("world_from_cam") is None:
            raise DropUnit("pose_missing", f"{root}: frame {view_id} has no pose")
        K, W, H = _K(f.get("intrinsics") or meta.get("intrinsics"))
        pose = to_h(f["world_from_cam"])
        rgb = read_rgb(V.file_in(root, f.get("image"), f"frame {view_id} image"))
        depth = (
            read_depth(V.file_in(root, f["depth"], f"frame {view_id} depth"), _encoding(meta))
            if f.get("depth")
            else None
        )
        per_frame = bool(meta.get("boxes_per_frame", False))
        boxes = parse_objects(f.get("objects", []) if per_frame else meta.get("objects", []), f"scan.json:{view_id}")
        cam = camera_from_K(K, W, H, pose, str(meta.get("pixel_origin", "center")))
        scene_id = meta.get("scene_id", root.name)
        view = ScanView(
            "generic",
            str(scene_id),
            view_id,
            rgb,
            depth,
            cam,
            boxes,
            "given",
            boxes_per_frame=per_frame,
            meta={"intrinsics_source": "scan.json"},
        )
        up = meta.get("up")
        if up is not None:
            up = V.matrix(up, ((3,),), "scan.json up")
            if not np.linalg.norm(up) > 0:
                raise DropUnit("annotation_invalid", "scan.json up must not be a zero vector")
        return level_views(view, up, lambda: _all_points(str(root.resolve())))


@lru_cache(maxsize=8)
def _all_points(root_s: str) -> tuple[np.ndarray, np.ndarray]:
    """World points of every frame (subsampled) and the mean camera up, for the floor fit (cached per scene).
    Frames that cannot be used (no pose, no depth, malformed) are left out of the fit."""
    root = Path(root_s)
    meta, frames = _meta(root)
    pts, ups = [], []
    for _k, f in sorted(enumerate(frames), key=lambda kf: _frame_id(kf[1], kf[0])):
        if not isinstance(f, dict) or f.get("world_from_cam") is None or not f.get("depth"):
            continue
        try:
            K, W, H = _K(f.get("intrinsics") or meta.get("intrinsics"))
            cam = camera_from_K(K, W, H, to_h(f["world_from_cam"]), str(meta.get("pixel_origin", "center")))
            d = read_depth(V.file_in(root, f["depth"], "depth"), _encoding(meta))
        except DropUnit:
            continue
        if d.shape == (H, W) and np.all(np.isfinite(d)):
            pts.append(cam.depth_to_points(d, stride=8))
            ups.append(cam.world_from_cam[:3, :3] @ np.array([0.0, -1.0, 0.0]))
    if not pts:
        return np.zeros((0, 3)), np.array([0.0, 0.0, 1.0])
    return np.concatenate(pts), np.mean(ups, axis=0)
