"""ScanNet scenes as packaged in scene.json: posed colour frames, aligned boxes, a point cloud, no depth.

The world frame is ScanNet's axis-aligned frame (`axis_align_matrix @ raw`), z up, so gravity is known.
Depth is derived per frame by splatting the point cloud (see splat.py), which also decides visibility.
K_color follows the OpenCV pixel-centre convention.
"""

from __future__ import annotations

from functools import lru_cache
from pathlib import Path
from typing import Any

import numpy as np

from refspatial_gen.core.errors import DropUnit
from refspatial_gen.sources.scan.fileio import read_rgb
from refspatial_gen.sources.scan.readers.common import box_from_json, camera_from_K, read_json, read_ply_xyz, to_h
from refspatial_gen.sources.scan.view import ScanBox, ScanView


@lru_cache(maxsize=4)
def _scene(root: str) -> tuple[dict, np.ndarray]:
    """scene.json and the aligned point cloud (cached: every frame of a scene shares them)."""
    meta = read_json(Path(root) / "scene.json")
    A = np.asarray(meta.get("axis_align_matrix", np.eye(4)), float)
    ply = Path(root) / str(meta.get("points_file", "points_raw.ply"))
    pts = np.zeros((0, 3))
    if ply.is_file():
        xyz, _ = read_ply_xyz(ply)
        pts = xyz @ A[:3, :3].T + A[:3, 3]
    return meta, pts


class ScanNetReader:
    name = "scannet"

    def detect(self, root: Path) -> bool:
        p = Path(root) / "scene.json"
        return p.is_file() and "axis_align_matrix" in p.read_text()

    def views(self, root: Path, config: dict[str, Any]) -> list[str]:
        meta, _ = _scene(str(Path(root).resolve()))
        return sorted(Path(f["image"]).stem for f in meta.get("frames", []))

    def read(self, root: Path, view_id: str, config: dict[str, Any]) -> ScanView:
        root = Path(root).resolve()
        meta, pts = _scene(str(root))
        frames = {Path(f["image"]).stem: f for f in meta.get("frames", [])}
        f = frames.get(view_id)
        if f is None:
            raise DropUnit("frame_missing", f"{root}: no frame {view_id}")
        if f.get("cam_to_world") is None:
            raise DropUnit("pose_missing", f"{root}: frame {view_id} has no pose")
        pose = to_h(f["cam_to_world"])
        if not np.all(np.isfinite(pose)):
            raise DropUnit("pose_invalid", f"{root}: frame {view_id} pose has NaN/inf (ScanNet marks lost tracking so)")
        A = np.asarray(meta.get("axis_align_matrix", np.eye(4)), float)
        rgb = read_rgb(root / f["image"])
        W, H = meta.get("image_size", [rgb.shape[1], rgb.shape[0]])
        cam = camera_from_K(meta["K_color"], W, H, A @ pose, pixel_origin="center", gravity_known=True)
        boxes = []
        for o in meta.get("objects", []):
            try:
                box = box_from_json(o["aligned_box"])
                oid = int(o["id"]) + 1
            except (KeyError, TypeError, ValueError) as e:
                raise DropUnit("annotation_invalid", f"{root}: {e}") from e
            boxes.append(ScanBox(oid, str(o["category"]), box,
                                 provenance={"annotation": "scannet", "nyu40_name": o.get("nyu40_name")}))
        if len(pts) == 0:
            raise DropUnit("points_missing", f"{root}: no point cloud to derive depth from")
        return ScanView("scannet", str(meta.get("scene_id", root.name)), view_id, rgb, None, cam, boxes,
                        "scan_z_up", boxes_per_frame=False, points=pts,
                        meta={"intrinsics_source": "K_color"})
