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

from refspatial_gen.core.errors import DropUnit
from refspatial_gen.sources.scan.fileio import read_depth, read_rgb
from refspatial_gen.sources.scan.readers.common import camera_from_K, parse_objects, read_json, to_h
from refspatial_gen.sources.scan.readers.leveling import level_views
from refspatial_gen.sources.scan.view import ScanView


def _K(d: dict[str, Any]) -> tuple[np.ndarray, int, int]:
    K = np.array([[d["fx"], 0, d["cx"]], [0, d["fy"], d["cy"]], [0, 0, 1.0]], float)
    return K, int(d["width"]), int(d["height"])


class GenericReader:
    name = "generic"

    def detect(self, root: Path) -> bool:
        p = Path(root) / "scan.json"
        return p.is_file() and "refspatial-scan/" in p.read_text()[:2000]

    def views(self, root: Path, config: dict[str, Any]) -> list[str]:
        meta = read_json(Path(root) / "scan.json")
        return sorted(str(f["id"]) for f in meta.get("frames", []))

    def read(self, root: Path, view_id: str, config: dict[str, Any]) -> ScanView:
        root = Path(root)
        meta = read_json(root / "scan.json")
        frames = {str(f["id"]): f for f in meta.get("frames", [])}
        f = frames.get(view_id)
        if f is None:
            raise DropUnit("frame_missing", f"{root}: no frame {view_id}")
        if f.get("world_from_cam") is None:
            raise DropUnit("pose_missing", f"{root}: frame {view_id} has no pose")
        try:
            K, W, H = _K(f.get("intrinsics") or meta["intrinsics"])
        except (KeyError, TypeError, ValueError) as e:
            raise DropUnit("intrinsics_invalid", f"{root}: frame {view_id}: {e}") from e
        pose = to_h(f["world_from_cam"])
        rgb = read_rgb(root / f["image"])
        depth = read_depth(root / f["depth"], str(meta.get("depth_encoding", "mm"))) if f.get("depth") else None
        per_frame = bool(meta.get("boxes_per_frame", False))
        boxes = parse_objects(f.get("objects", []) if per_frame else meta.get("objects", []), f"scan.json:{view_id}")
        cam = camera_from_K(K, W, H, pose, str(meta.get("pixel_origin", "center")))
        view = ScanView("generic", str(meta.get("scene_id", root.name)), view_id, rgb, depth, cam, boxes, "given",
                        boxes_per_frame=per_frame, meta={"intrinsics_source": "scan.json"})
        up = meta.get("up")
        return level_views(view, None if up is None else np.asarray(up, float), lambda: _all_points(str(root.resolve())))


@lru_cache(maxsize=8)
def _all_points(root_s: str) -> tuple[np.ndarray, np.ndarray]:
    """World points of every frame (subsampled) and the mean camera up, for the floor fit (cached per scene)."""
    root = Path(root_s)
    meta = read_json(root / "scan.json")
    pts, ups = [], []
    for f in sorted(meta.get("frames", []), key=lambda f: str(f["id"])):
        if f.get("world_from_cam") is None or not f.get("depth"):
            continue
        K, W, H = _K(f.get("intrinsics") or meta["intrinsics"])
        cam = camera_from_K(K, W, H, to_h(f["world_from_cam"]), str(meta.get("pixel_origin", "center")))
        try:
            d = read_depth(root / f["depth"], str(meta.get("depth_encoding", "mm")))
        except DropUnit:
            continue
        if d.shape == (H, W) and np.all(np.isfinite(d)):
            pts.append(cam.depth_to_points(d, stride=8))
            ups.append(cam.world_from_cam[:3, :3] @ np.array([0.0, -1.0, 0.0]))
    if not pts:
        return np.zeros((0, 3)), np.array([0.0, 0.0, 1.0])
    return np.concatenate(pts), np.mean(ups, axis=0)
