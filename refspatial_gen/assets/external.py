"""External meshes (OBJ, GLB/GLTF, STL, PLY, USD) as catalog categories.

The mesh is moved so that its bounding-box bottom centre is the object origin (the convention of
procedural assets); collision is the mesh's convex hull ("hull") or a folder of convex parts (a
decomposition shipped with the mesh). Files are read once per process (lru_cache) because a scanned
mesh takes ~0.1 s to parse.
"""

from __future__ import annotations

from functools import lru_cache
from pathlib import Path

import numpy as np
import trimesh

from refspatial_gen.assets.catalog import Category, resolve_external
from refspatial_gen.assets.shapes import AssetGeometry, Part
from refspatial_gen.core.errors import DropUnit

MESH_SUFFIXES = (".obj", ".stl", ".ply", ".glb", ".gltf", ".off")
USD_SUFFIXES = (".usd", ".usda", ".usdc", ".usdz")


def _load_usd(path: Path) -> trimesh.Trimesh:
    """All UsdGeom.Mesh prims of a stage, in stage units converted to metres, as one triangle mesh."""
    from pxr import Usd, UsdGeom

    stage = Usd.Stage.Open(str(path))
    mpu = UsdGeom.GetStageMetersPerUnit(stage) or 1.0
    up = UsdGeom.GetStageUpAxis(stage)
    meshes = []
    for prim in stage.Traverse():
        if not prim.IsA(UsdGeom.Mesh):
            continue
        mesh = UsdGeom.Mesh(prim)
        pts = np.asarray(mesh.GetPointsAttr().Get(), float)
        counts = np.asarray(mesh.GetFaceVertexCountsAttr().Get(), int)
        idx = np.asarray(mesh.GetFaceVertexIndicesAttr().Get(), int)
        xf = np.asarray(UsdGeom.Xformable(prim).ComputeLocalToWorldTransform(Usd.TimeCode.Default()), float)
        pts = (np.c_[pts, np.ones(len(pts))] @ xf)[:, :3]  # USD matrices are row-vector convention
        faces, k = [], 0
        for c in counts:  # fan triangulation
            faces += [[idx[k], idx[k + j], idx[k + j + 1]] for j in range(1, c - 1)]
            k += c
        meshes.append(trimesh.Trimesh(pts * mpu, np.asarray(faces), process=False))
    if not meshes:
        raise ValueError(f"{path}: no UsdGeom.Mesh prims")
    m = trimesh.util.concatenate(meshes)
    if up == UsdGeom.Tokens.y:
        m.apply_transform(trimesh.transformations.rotation_matrix(np.pi / 2, [1, 0, 0]))
    return m


def load_mesh_file(path: Path) -> trimesh.Trimesh:
    """Any supported mesh file -> one Trimesh (scenes are flattened with their transforms)."""
    suffix = path.suffix.lower()
    if suffix in USD_SUFFIXES:
        return _load_usd(path)
    if suffix not in MESH_SUFFIXES:
        raise ValueError(f"{path}: unsupported mesh format {suffix} (use {', '.join(MESH_SUFFIXES + USD_SUFFIXES)})")
    loaded = trimesh.load(str(path), process=False, maintain_order=True)
    if isinstance(loaded, trimesh.Scene):
        loaded = loaded.to_mesh()
    return loaded


@lru_cache(maxsize=64)
def _external_geometry(mesh: str, collision: str, texture: str, scale: float) -> tuple[AssetGeometry, tuple]:
    path = resolve_external(mesh)
    if not path.exists():
        raise FileNotFoundError(str(path))
    m = load_mesh_file(path)
    lo, hi = m.bounds * scale
    offset = -np.array([(lo[0] + hi[0]) / 2, (lo[1] + hi[1]) / 2, lo[2]])
    verts = np.asarray(m.vertices, float) * scale + offset
    uv = None
    tex = None
    if texture:
        vis = getattr(m, "visual", None)
        if vis is not None and getattr(vis, "uv", None) is not None and len(vis.uv) == len(verts):
            uv = np.asarray(vis.uv, float)
            tex = str(resolve_external(texture))
    vis_mesh = trimesh.Trimesh(verts, np.asarray(m.faces), process=False)
    if collision == "hull":
        parts = [Part("mesh", mesh=vis_mesh, uv=uv, texture=tex, collide=True)]
        return AssetGeometry(parts, density=400), (path,)
    parts = [Part("mesh", mesh=vis_mesh, uv=uv, texture=tex, collide=False)]
    cdir = resolve_external(collision)
    files = sorted(cdir.glob("*.stl"), key=lambda p: (len(p.name), p.name)) if cdir.is_dir() else []
    if not files:
        raise FileNotFoundError(f"{cdir}: no convex collision parts (*.stl)")
    for f in files:
        c = load_mesh_file(f)
        parts.append(Part("mesh", mesh=trimesh.Trimesh(np.asarray(c.vertices) * scale + offset, c.faces, process=False), visual=False))
    return AssetGeometry(parts, density=400), (path,)


def external_available(cat: Category) -> bool:
    return resolve_external(cat.external["mesh"]).exists()


def build_external(cat: Category) -> AssetGeometry:
    """The geometry of an external category (shared, cached: callers must not mutate it)."""
    e = cat.external
    try:
        geo, _ = _external_geometry(str(e["mesh"]), str(e.get("collision", "hull")), str(e.get("texture", "")),
                                    float(e.get("scale", 1.0)))
    except (FileNotFoundError, ValueError) as err:
        raise DropUnit("asset_unreadable", f"{cat.name}: {err}") from err
    return geo
