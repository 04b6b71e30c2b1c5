"""SUN RGB-D single frames (votenet export): annotation.json + image.jpg + depth.png (mm).

World frame = SUN's upright camera-centred frame (x right, y forward, z up), tied to the camera by Rtilt:
p_cv = F @ Rtilt.T @ p with F = [[1,0,0],[0,0,-1],[0,1,0]], so world_from_cam = Rtilt @ F.T and gravity
is known. K in annotation.json is 0-based (pixel centres at integers); 2D boxes are 1-based MATLAB pixels.
Boxes are annotated for this very frame, so one behind the camera drops the frame.
"""

from __future__ import annotations

from pathlib import Path
from typing import Any

import numpy as np

from refspatial_gen.core.errors import DropUnit
from refspatial_gen.core.geometry import Box3D, rot_z
from refspatial_gen.sources.scan.fileio import read_depth, read_rgb
from refspatial_gen.sources.scan.readers import validate as V
from refspatial_gen.sources.scan.readers.common import camera_from_K, read_json
from refspatial_gen.sources.scan.view import ScanBox, ScanView

F = np.array([[1.0, 0, 0], [0, 0, -1.0], [0, 1.0, 0]])


def _is_sample(p: Path) -> bool:
    try:
        return (p / "annotation.json").is_file() and '"Rtilt"' in (p / "annotation.json").read_text(
            encoding="utf-8", errors="replace"
        )
    except OSError:
        return False


class SunRGBDReader:
    name = "sunrgbd"

    def detect(self, root: Path) -> bool:
        root = Path(root)
        if not root.is_dir():
            return False
        return _is_sample(root) or any(_is_sample(c) for c in sorted(root.iterdir()) if c.is_dir())

    def views(self, root: Path, config: dict[str, Any]) -> list[str]:
        root = Path(root)
        if _is_sample(root):
            return ["."]
        return sorted(c.name for c in root.iterdir() if c.is_dir() and (c / "annotation.json").is_file())

    def read(self, root: Path, view_id: str, config: dict[str, Any]) -> ScanView:
        folder = Path(root) / view_id
        ann = V.mapping(read_json(folder / "annotation.json"), f"{view_id}/annotation.json")
        Rtilt = V.matrix(ann.get("Rtilt"), ((3, 3),), f"{folder}: Rtilt", "pose_invalid")
        W = V.positive_int(ann.get("width"), f"{folder}: width")
        H = V.positive_int(ann.get("height"), f"{folder}: height")
        scale = V.number(ann.get("depth_scale", 1000.0), f"{folder}: depth_scale")
        if scale <= 0:
            raise DropUnit("annotation_invalid", f"{folder}: depth_scale must be > 0")
        T = np.eye(4)
        T[:3, :3] = Rtilt @ F.T
        rgb = read_rgb(V.file_in(folder, ann.get("image", "image.jpg"), "image"))
        depth = read_depth(V.file_in(folder, ann.get("depth", "depth.png"), "depth"), "mm") * np.float32(1000.0 / scale)
        cam = camera_from_K(ann.get("K"), W, H, T, pixel_origin="center", gravity_known=True)
        boxes = [_box(o, k, folder) for k, o in enumerate(V.listing(ann.get("objects", []), f"{folder}: objects"))]
        scene = folder.resolve().name
        return ScanView(
            "sunrgbd",
            scene,
            scene,
            rgb,
            depth,
            cam,
            boxes,
            "rtilt",
            boxes_per_frame=True,
            meta={"intrinsics_source": "annotation", "depth_source": "sensor"},
        )


def _box(o: Any, k: int, folder: Path) -> ScanBox:
    """One annotated object; anything malformed drops the view (annotation_invalid)."""
    try:
        o = V.mapping(o, "object")
        size = V.matrix(o.get("size"), ((3,),), "size")
        if np.any(size < 0):
            raise DropUnit("annotation_invalid", f"size must be >= 0, got {size.tolist()}")
        box = Box3D(V.matrix(o.get("center"), ((3,),), "center"), size, rot_z(V.number(o.get("yaw"), "yaw")))
        if not isinstance(o.get("category"), str) or not o["category"]:
            raise DropUnit("annotation_invalid", "category must be a name")
        b2 = o.get("bbox2d_xyxy")
        prov: dict[str, Any] = {"annotation": "sunrgbd"}
        if b2 is not None:  # 1-based MATLAB pixel corners -> 0-based
            b2 = V.matrix(b2, ((4,),), "bbox2d_xyxy")
            prov["bbox2d_annotated"] = [
                round(float(b2[0]) - 1, 3),
                round(float(b2[1]) - 1, 3),
                round(float(b2[2]) - 1, 3),
                round(float(b2[3]) - 1, 3),
            ]
    except DropUnit as e:
        raise DropUnit(e.reason, f"{folder}: object {k}: {e.detail}") from None
    return ScanBox(k + 1, o["category"], box, provenance=prov)
