"""USD meshes (usd-core) as drawn sub-meshes: points in metres, z up, UVs (`st`), textures and colours.

Why its own reader: trimesh does not read USD. Each UsdGeom.Mesh prim is one sub-mesh with its world
transform; `primvars:st` (vertex or faceVarying) gives UVs, the bound UsdPreviewSurface's diffuseColor
texture (UsdUVTexture `inputs:file`) or constant colour gives its look, `displayColor` otherwise.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
import trimesh


def _triangulate(counts: np.ndarray, idx: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Fan triangles as (vertex indices, face-corner indices)."""
    tris, corners, k = [], [], 0
    for c in counts:
        for j in range(1, c - 1):
            tris.append([idx[k], idx[k + j], idx[k + j + 1]])
            corners.append([k, k + j, k + j + 1])
        k += c
    return np.asarray(tris, int).reshape(-1, 3), np.asarray(corners, int).reshape(-1, 3)


def _material_look(prim, path: Path):
    """(texture file or None, rgb or None) from the prim's bound UsdPreviewSurface."""
    from pxr import UsdShade

    mat, _ = UsdShade.MaterialBindingAPI(prim).ComputeBoundMaterial()
    if not mat:
        return None, None
    for sh in mat.GetPrim().GetChildren():
        shader = UsdShade.Shader(sh)
        if not shader or shader.GetIdAttr().Get() != "UsdPreviewSurface":
            continue
        inp = shader.GetInput("diffuseColor")
        if inp is None:
            return None, None
        if inp.HasConnectedSource():
            src = inp.GetConnectedSource()[0]
            f = UsdShade.Shader(src.GetPrim()).GetInput("file")
            asset = f.Get() if f else None
            if asset is not None:
                p = Path(asset.resolvedPath or (path.parent / asset.path))
                return (str(p) if p.exists() else None), None
        val = inp.Get()
        return None, (tuple(float(x) for x in val) if val is not None else None)
    return None, None


def load_usd_visuals(path: Path) -> list:
    """All UsdGeom.Mesh prims of a stage, converted to metres and z up, as VisualMesh records."""
    from PIL import Image
    from pxr import Usd, UsdGeom

    from refspatial_gen.assets.external import VisualMesh, _pixels

    stage = Usd.Stage.Open(str(path))
    mpu = UsdGeom.GetStageMetersPerUnit(stage) or 1.0
    up_y = UsdGeom.GetStageUpAxis(stage) == UsdGeom.Tokens.y
    fix = np.array([[1.0, 0, 0], [0, 0, -1], [0, 1, 0]]) if up_y else np.eye(3)
    out = []
    for prim in stage.Traverse():
        if not prim.IsA(UsdGeom.Mesh):
            continue
        mesh = UsdGeom.Mesh(prim)
        pts = np.asarray(mesh.GetPointsAttr().Get(), float)
        counts = np.asarray(mesh.GetFaceVertexCountsAttr().Get(), int)
        idx = np.asarray(mesh.GetFaceVertexIndicesAttr().Get(), int)
        xf = np.asarray(UsdGeom.Xformable(prim).ComputeLocalToWorldTransform(Usd.TimeCode.Default()), float)
        pts = ((np.c_[pts, np.ones(len(pts))] @ xf)[:, :3] * mpu) @ fix.T  # USD matrices act on row vectors
        tris, corners = _triangulate(counts, idx)
        v = VisualMesh(trimesh.Trimesh(pts, tris, process=False))
        st = UsdGeom.PrimvarsAPI(prim).GetPrimvar("st")
        tex, rgb = _material_look(prim, path)
        if st and st.HasValue():
            uv = np.asarray(st.ComputeFlattened(), float)
            interp = st.GetInterpolation()
            if interp == UsdGeom.Tokens.faceVarying and len(uv) == len(idx):  # one vertex per face corner
                v.mesh = trimesh.Trimesh(pts[tris.ravel()], np.arange(tris.size).reshape(-1, 3), process=False)
                v.uv = uv[corners.ravel()]
            elif len(uv) == len(pts):
                v.uv = uv
        if tex and v.uv is not None:
            v.image, v.texture = _pixels(Image.open(tex)), tex
        elif rgb is not None:
            v.rgba = (*rgb[:3], 1.0)
        else:
            dc = mesh.GetDisplayColorAttr().Get()
            if dc is not None and len(dc):
                v.rgba = (*np.asarray(dc, float).mean(axis=0)[:3].tolist(), 1.0)
        out.append(v)
    if not out:
        raise ValueError(f"{path}: no UsdGeom.Mesh prims")
    return out
