"""USD stages through usd-core: labelled prims become oriented boxes; views are rendered with MuJoCo.

* Objects: every prim with a semantic class label (UsdSemantics.LabelsAPI `semantics:labels:class`,
  or the older Isaac Sim `semantic:*:params:semanticData`) -> its world bounding box (UsdGeom.BBoxCache,
  oriented: the box follows the prim's transform). Ids are the labelled prims in path order, from 1.
* Geometry rendered: every UsdGeom.Mesh and UsdGeom.Cube (displayColor when authored).
* Views: every UsdGeom.Camera prim (USD cameras look down -Z with +Y up), or recipe `options.views`
  [{eye: [x,y,z], target: [x,y,z]}] with `options.width`, `height`, `fovy` (degrees).
* Units and gravity: metersPerUnit scales to metres; the stage up axis (Z or Y) is rotated to +z, so
  gravity is known (gravity_source "given").
"""

from __future__ import annotations

from functools import lru_cache
from pathlib import Path
from typing import Any

import numpy as np

from refspatial_gen.core.camera import look_at
from refspatial_gen.core.errors import DropUnit
from refspatial_gen.core.geometry import Box3D
from refspatial_gen.sources.scan.render import RenderGeom, render, render_camera
from refspatial_gen.sources.scan.view import ScanBox, ScanView

EXT = (".usd", ".usda", ".usdc")


def _m(gf) -> np.ndarray:
    """Gf.Matrix4d (row-vector convention) -> 4x4 column-vector numpy matrix."""
    return np.array(gf, float).T


def prim_label(prim) -> str | None:
    for attr in prim.GetAttributes():
        n = attr.GetName()
        if (n.startswith("semantics:labels:") and n.endswith("class")) or n == "semantics:labels:class":
            v = attr.Get()
            if v:
                return str(list(v)[0])
        if n.startswith("semantic:") and n.endswith(":params:semanticData"):
            v = attr.Get()
            if v:
                return str(v)
    return None


@lru_cache(maxsize=4)
def _stage(path: str) -> dict[str, Any]:
    from pxr import Usd, UsdGeom

    stage = Usd.Stage.Open(path)
    if stage is None:
        raise DropUnit("stage_unreadable", path)
    mpu = float(UsdGeom.GetStageMetersPerUnit(stage) or 1.0)
    up = str(UsdGeom.GetStageUpAxis(stage))
    L = np.eye(4)  # stage -> metric z-up world
    if up == "Y":
        L[:3, :3] = np.array([[1.0, 0, 0], [0, 0, -1.0], [0, 1.0, 0]])
    L[:3, :3] *= mpu
    cache = UsdGeom.BBoxCache(Usd.TimeCode.Default(), [UsdGeom.Tokens.default_, UsdGeom.Tokens.render])
    xf = UsdGeom.XformCache(Usd.TimeCode.Default())
    boxes, geoms, cams = [], [], {}
    for prim in sorted(stage.Traverse(), key=lambda p: str(p.GetPath())):
        label = prim_label(prim)
        if label is not None and prim.IsA(UsdGeom.Imageable):
            bb = cache.ComputeWorldBound(prim)
            rng = bb.GetRange()
            if rng.IsEmpty():
                raise DropUnit("annotation_invalid", f"labelled prim {prim.GetPath()} has an empty bound")
            M = L @ _m(bb.GetMatrix())
            lo, hi = np.array(rng.GetMin()), np.array(rng.GetMax())
            A = M[:3, :3]
            norms = np.linalg.norm(A, axis=0)
            boxes.append(
                ScanBox(
                    len(boxes) + 1,
                    label,
                    Box3D(M[:3, :3] @ ((lo + hi) / 2) + M[:3, 3], (hi - lo) * norms, A / norms),
                    provenance={"annotation": "usd", "prim": str(prim.GetPath())},
                )
            )
        if prim.IsA(UsdGeom.Mesh) or prim.IsA(UsdGeom.Cube):
            W = L @ _m(xf.GetLocalToWorldTransform(prim))
            colour = (0.7, 0.7, 0.7, 1.0)
            dc = UsdGeom.Gprim(prim).GetDisplayColorAttr().Get()
            if dc:
                colour = (*[float(c) for c in dc[0]], 1.0)
            if prim.IsA(UsdGeom.Cube):
                s = float(UsdGeom.Cube(prim).GetSizeAttr().Get() or 2.0)
                A = W[:3, :3]
                n = np.linalg.norm(A, axis=0)
                geoms.append(RenderGeom(str(prim.GetPath()), W[:3, 3], s * n, A / n, rgba=colour))
            else:
                mesh = UsdGeom.Mesh(prim)
                pts = np.array(mesh.GetPointsAttr().Get(), float)
                counts = list(mesh.GetFaceVertexCountsAttr().Get())
                idx = list(mesh.GetFaceVertexIndicesAttr().Get())
                tris, k = [], 0
                for c in counts:  # fan triangulation
                    tris += [[idx[k], idx[k + j], idx[k + j + 1]] for j in range(1, c - 1)]
                    k += c
                geoms.append(
                    RenderGeom(
                        str(prim.GetPath()),
                        vertices=pts @ W[:3, :3].T + W[:3, 3],
                        faces=np.array(tris, int),
                        rgba=colour,
                    )
                )
        if prim.IsA(UsdGeom.Camera):
            cam = UsdGeom.Camera(prim).GetCamera(Usd.TimeCode.Default())
            W = L @ _m(xf.GetLocalToWorldTransform(prim))
            R = W[:3, :3] / np.linalg.norm(W[:3, :3], axis=0)
            T = np.eye(4)
            T[:3, :3], T[:3, 3] = R @ np.diag([1.0, -1.0, -1.0]), W[:3, 3]
            fovy = float(np.degrees(2 * np.arctan(cam.verticalAperture / (2 * cam.focalLength))))
            cams[str(prim.GetPath()).strip("/").replace("/", ".")] = (T, fovy)
    return {"boxes": boxes, "geoms": geoms, "cams": cams, "up_axis": up, "meters_per_unit": mpu}


class UsdReader:
    name = "usd"

    def _file(self, root: Path) -> Path | None:
        root = Path(root)
        if root.is_file() and root.suffix in EXT:
            return root
        if root.is_dir():
            files = sorted(p for p in root.iterdir() if p.suffix in EXT)
            return files[0] if files else None
        return None

    def detect(self, root: Path) -> bool:
        return self._file(root) is not None

    def _views(self, st: dict[str, Any], config: dict[str, Any]) -> dict[str, tuple[np.ndarray, float]]:
        opts = config.get("options") or {}
        if opts.get("views"):
            fovy = float(opts.get("fovy", 60.0))
            return {
                f"view{k:03d}": (look_at(np.array(v["eye"], float), np.array(v["target"], float)), fovy)
                for k, v in enumerate(opts["views"])
            }
        return st["cams"]

    def views(self, root: Path, config: dict[str, Any]) -> list[str]:
        f = self._file(root)
        return sorted(self._views(_stage(str(f.resolve())), config)) if f else []

    def read(self, root: Path, view_id: str, config: dict[str, Any]) -> ScanView:
        f = self._file(root)
        st = _stage(str(f.resolve()))
        views = self._views(st, config)
        if view_id not in views:
            raise DropUnit("pose_missing", f"{f}: no camera {view_id}")
        opts = config.get("options") or {}
        T, fovy = views[view_id]
        cam = render_camera(int(opts.get("width", 640)), int(opts.get("height", 480)), fovy, T)
        if not st["geoms"]:
            raise DropUnit("stage_empty", f"{f}: no mesh or cube to render")
        ((rgb, depth, _),) = render(st["geoms"], [cam])
        return ScanView(
            "usd",
            f.stem,
            view_id,
            rgb,
            depth,
            cam,
            list(st["boxes"]),
            "given",
            boxes_per_frame=False,
            meta={
                "intrinsics_source": "usd_camera" if not opts.get("views") else "recipe",
                "depth_source": "rendered",
                "up_axis": st["up_axis"],
                "meters_per_unit": st["meters_per_unit"],
            },
        )
