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

from refspatial_gen.core.errors import DropUnit, InputError
from refspatial_gen.sources.scan.fileio import read_rgb
from refspatial_gen.sources.scan.readers import validate as V
from refspatial_gen.sources.scan.readers.common import box_from_json, camera_from_K, read_json, read_ply_xyz, to_h
from refspatial_gen.sources.scan.view import ScanBox, ScanView


def _meta(root: str) -> tuple[dict, list]:
    """scene.json (it lists the views, so an unreadable one stops planning: InputError) and its frame list."""
    path = Path(root) / "scene.json"
    try:
        st = path.stat()
        stamp = (st.st_mtime_ns, st.st_size)
    except OSError:
        stamp = None
    return _meta_cached(root, stamp)


@lru_cache(maxsize=4)
def _meta_cached(root: str, stamp: tuple | None) -> tuple[dict, list]:
    path = Path(root) / "scene.json"
    meta = V.index_json(path)
    return meta, V.view_list(meta, path)


def _view_id(f: Any, k: int) -> str:
    """A frame's view id: its image's stem; a malformed entry gets `!frame<k>` (dropped when read)."""
    if (
        isinstance(f, dict)
        and isinstance(f.get("image"), str)
        and Path(f["image"]).stem
        and "#" not in f["image"]
        and not Path(f["image"]).stem.startswith("!")
    ):
        return Path(f["image"]).stem
    return f"!frame{k}"


@lru_cache(maxsize=4)
def _points(root: str, points_file: str, align: tuple) -> np.ndarray:
    """The aligned point cloud (cached: every frame of a scene shares it); read at load time, never planning."""
    A = np.asarray(align, float).reshape(4, 4)
    ply = V.file_in(Path(root), points_file, "points_file")
    if not ply.is_file():
        return np.zeros((0, 3))
    xyz, _ = read_ply_xyz(ply)
    return xyz @ A[:3, :3].T + A[:3, 3]


def _boxes(meta: dict, root: Path) -> list[ScanBox]:
    boxes = []
    for k, o in enumerate(V.listing(meta.get("objects", []), "scene.json objects")):
        try:
            o = V.mapping(o, "object")
            box = box_from_json(o.get("aligned_box"))
            oid = o.get("id")
            if isinstance(oid, bool) or not isinstance(oid, int) or oid < 0:
                raise DropUnit("annotation_invalid", f"id must be an integer >= 0, got {V.short(oid)}")
            if not isinstance(o.get("category"), str) or not o["category"]:
                raise DropUnit("annotation_invalid", "category must be a name")
        except DropUnit as e:
            raise DropUnit(e.reason, f"{root.name}/scene.json object {k}: {e.detail}") from None
        boxes.append(
            ScanBox(
                oid + 1, o["category"], box, provenance={"annotation": "scannet", "nyu40_name": o.get("nyu40_name")}
            )
        )
    return boxes


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
        try:
            return p.is_file() and "axis_align_matrix" in p.read_text(encoding="utf-8", errors="replace")
        except OSError:
            return False

    def views(self, root: Path, config: dict[str, Any]) -> list[str]:
        _, frames = _meta(str(Path(root).resolve()))
        return sorted({_view_id(f, k) for k, f in enumerate(frames)})

    def read(self, root: Path, view_id: str, config: dict[str, Any]) -> ScanView:
        root = Path(root).resolve()
        try:
            meta, frames = _meta(str(root))
        except InputError as e:  # changed since planning
            raise DropUnit("annotation_invalid", str(e)) from None
        matches = [f for k, f in enumerate(frames) if _view_id(f, k) == view_id]
        if not matches:
            raise DropUnit("frame_missing", f"{root}: no frame {view_id}")
        if view_id.startswith("!") or len(matches) > 1:
            raise DropUnit(
                "annotation_invalid",
                f"{root.name}/scene.json {view_id}: {'listed twice' if len(matches) > 1 else 'no image file name'}",
            )
        f = matches[0]
        if f.get("cam_to_world") is None:
            raise DropUnit("pose_missing", f"{root}: frame {view_id} has no pose")
        pose = to_h(f["cam_to_world"])  # NaN/inf (ScanNet marks lost tracking so) -> pose_invalid
        A = V.matrix(meta.get("axis_align_matrix", np.eye(4).tolist()), ((4, 4),), "axis_align_matrix", "pose_invalid")
        rgb = read_rgb(V.file_in(root, f["image"], f"frame {view_id} image"))
        size = meta.get("image_size", [rgb.shape[1], rgb.shape[0]])
        if not isinstance(size, list) or len(size) != 2:
            raise DropUnit("intrinsics_invalid", f"{root.name}/scene.json image_size must be [width, height]")
        cam = camera_from_K(meta.get("K_color"), size[0], size[1], A @ pose, pixel_origin="center", gravity_known=True)
        boxes = _boxes(meta, root)
        pts = _points(str(root), meta.get("points_file", "points_raw.ply"), tuple(A.reshape(-1).tolist()))
        if len(pts) == 0:
            raise DropUnit("points_missing", f"{root}: no point cloud to derive depth from")
        view = ScanView(
            "scannet",
            str(meta.get("scene_id", root.name)),
            view_id,
            rgb,
            None,
            cam,
            boxes,
            "scan_z_up",
            boxes_per_frame=False,
            points=pts,
            meta={"intrinsics_source": "K_color"},
        )
        if (config or {}).get("instance_labels", True):
            from refspatial_gen.sources.scan.labels import box_instances

            labels, structural, note = _labels(str(root), len(pts))
            view.meta["instance_labels"] = note if labels is not None else f"none ({note})"
            if labels is not None:
                try:
                    explicit = {
                        int(o["id"]) + 1: (int(o["instance_id"]) if "instance_id" in o else int(o["object_id"]) + 1)
                        for o in meta.get("objects", [])
                        if "instance_id" in o or "object_id" in o
                    }
                except (TypeError, ValueError, OverflowError) as e:
                    raise DropUnit(
                        "annotation_invalid", f"{root.name}/scene.json: instance_id/object_id: {e}"
                    ) from None
                view.point_labels = labels
                view.box_instance = box_instances(boxes, pts, labels, explicit)
                view.meta["structural_instances"] = sorted(structural)
        return view
