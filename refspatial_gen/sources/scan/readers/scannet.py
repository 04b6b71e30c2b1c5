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


@lru_cache(maxsize=4)
def _labels(root: str, n_points: int) -> tuple[np.ndarray | None, frozenset, str]:
    """Per-point instance labels when the scene has them (sources/scan/labels.py): (labels, ids of
    wall/floor/ceiling instances, note), or (None, {}, why)."""
    from refspatial_gen.sources.scan.labels import ply_vertex_labels, scannet_labels

    meta = read_json(Path(root) / "scene.json")
    structural: set[int] = set()
    lab, note = scannet_labels(Path(root), meta, n_points, structural)
    if lab is None:
        ply = Path(root) / str(meta.get("points_file", "points_raw.ply"))
        if ply.is_file():
            lab2, note2 = ply_vertex_labels(ply, n_points)
            if lab2 is not None:
                return lab2, frozenset(), note2
    return lab, frozenset(structural), note


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
        view = ScanView("scannet", str(meta.get("scene_id", root.name)), view_id, rgb, None, cam, boxes,
                        "scan_z_up", boxes_per_frame=False, points=pts,
                        meta={"intrinsics_source": "K_color"})
        if (config or {}).get("instance_labels", True):
            from refspatial_gen.sources.scan.labels import box_instances

            labels, structural, note = _labels(str(root), len(pts))
            view.meta["instance_labels"] = note if labels is not None else f"none ({note})"
            if labels is not None:
                explicit = {int(o["id"]) + 1: (int(o["instance_id"]) if "instance_id" in o else int(o["object_id"]) + 1)
                            for o in meta.get("objects", []) if "instance_id" in o or "object_id" in o}
                view.point_labels = labels
                view.box_instance = box_instances(boxes, pts, labels, explicit)
                view.meta["structural_instances"] = sorted(structural)
        return view
