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
from refspatial_gen.sources.scan.readers.common import camera_from_K, read_json
from refspatial_gen.sources.scan.view import ScanBox, ScanView

F = np.array([[1.0, 0, 0], [0, 0, -1.0], [0, 1.0, 0]])


def _is_sample(p: Path) -> bool:
    return (p / "annotation.json").is_file() and '"Rtilt"' in (p / "annotation.json").read_text()


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
        ann = read_json(folder / "annotation.json")
        try:
            K = np.array(ann["K"], float)
            Rtilt = np.array(ann["Rtilt"], float)
            W, H = int(ann["width"]), int(ann["height"])
            scale = float(ann.get("depth_scale", 1000.0))
        except (KeyError, TypeError, ValueError) as e:
            raise DropUnit("annotation_invalid", f"{folder}: {e}") from e
        if Rtilt.shape != (3, 3) or not np.all(np.isfinite(Rtilt)):
            raise DropUnit("pose_invalid", f"{folder}: Rtilt {Rtilt.tolist()}")
        T = np.eye(4)
        T[:3, :3] = Rtilt @ F.T
        rgb = read_rgb(folder / ann.get("image", "image.jpg"))
        depth = read_depth(folder / ann.get("depth", "depth.png"), "mm") * np.float32(1000.0 / scale)
        cam = camera_from_K(K, W, H, T, pixel_origin="center", gravity_known=True)
        boxes = []
        for k, o in enumerate(ann.get("objects", [])):
            try:
                box = Box3D(np.array(o["center"], float), np.array(o["size"], float), rot_z(float(o["yaw"])))
                b2 = o.get("bbox2d_xyxy")
            except (KeyError, TypeError, ValueError) as e:
                raise DropUnit("annotation_invalid", f"{folder}: object {k}: {e}") from e
            prov: dict[str, Any] = {"annotation": "sunrgbd"}
            if b2 is not None:  # 1-based MATLAB pixel corners -> 0-based
                prov["bbox2d_annotated"] = [round(float(b2[0]) - 1, 3), round(float(b2[1]) - 1, 3),
                                            round(float(b2[2]) - 1, 3), round(float(b2[3]) - 1, 3)]
            boxes.append(ScanBox(k + 1, str(o["category"]), box, provenance=prov))
        scene = folder.resolve().name
        return ScanView("sunrgbd", scene, scene, rgb, depth, cam, boxes, "rtilt", boxes_per_frame=True,
                        meta={"intrinsics_source": "annotation", "depth_source": "sensor"})
