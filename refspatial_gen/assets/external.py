"""External meshes (OBJ+MTL, GLB/glTF, STL, PLY, OFF, USD) as catalog categories, with their own materials.

The mesh is turned so that the catalog's `up` axis of the file points to +z, scaled to metres, and moved
so that its bounding-box bottom centre is the object origin (the convention of procedural assets).
Every sub-mesh of the file stays a separate drawn part with what it was authored with: its UV
coordinates and texture image (downsampled to 512 px, enough for 640x480 frames), or its base colour.
Collision is the convex hull of the whole mesh ("hull") or a folder of convex parts (a decomposition
shipped with the mesh, or made by `assets import` with CoACD and cached by mesh hash). Files are read
once per process (lru_cache) because a scanned mesh takes ~0.1 s to parse.
"""

from __future__ import annotations

from dataclasses import dataclass
from functools import lru_cache
from pathlib import Path

import numpy as np
import trimesh

from refspatial_gen.assets.catalog import Category
from refspatial_gen.assets.shapes import AssetGeometry, Part
from refspatial_gen.core.errors import DropUnit

MESH_SUFFIXES = (".obj", ".stl", ".ply", ".glb", ".gltf", ".off")
USD_SUFFIXES = (".usd", ".usda", ".usdc", ".usdz")
TEXTURE_SIZE = 512
DEFAULT_DENSITY = 400.0  # kg/m^3 when the catalog gives no mass


@dataclass
class VisualMesh:
    """One drawn sub-mesh as authored: geometry in file units and axes, and its look."""

    mesh: trimesh.Trimesh
    uv: np.ndarray | None = None  # per vertex
    image: np.ndarray | None = None  # uint8 HxWx3, first row = top
    rgba: tuple[float, float, float, float] | None = None
    texture: str | None = None  # where the image came from


def up_rotation(up: str) -> np.ndarray:
    """Rotation taking the file's `up` axis to +z (a proper rotation, so handedness is kept)."""
    R = {
        "z": np.eye(3),
        "-z": np.diag([1.0, -1.0, -1.0]),
        "y": np.array([[1.0, 0, 0], [0, 0, -1], [0, 1, 0]]),
        "-y": np.array([[1.0, 0, 0], [0, 0, 1], [0, -1, 0]]),
        "x": np.array([[0, 0, -1.0], [0, 1, 0], [1, 0, 0]]),
        "-x": np.array([[0, 0, 1.0], [0, 1, 0], [-1, 0, 0]]),
    }
    return R[up]


def _pixels(img, size: int = TEXTURE_SIZE) -> np.ndarray:
    from PIL import Image

    im = img.convert("RGB") if hasattr(img, "convert") else Image.fromarray(np.asarray(img)[..., :3])
    if max(im.size) > size:
        im = im.resize((min(size, im.width), min(size, im.height)), Image.BILINEAR)
    return np.ascontiguousarray(np.asarray(im, np.uint8))


def _look(m: trimesh.Trimesh, where: str) -> VisualMesh:
    """Keep a trimesh's UV texture or base colour (SimpleMaterial from MTL, PBRMaterial from glTF)."""
    vis = getattr(m, "visual", None)
    out = VisualMesh(trimesh.Trimesh(np.asarray(m.vertices, float), np.asarray(m.faces), process=False))
    if vis is None:
        return out
    if getattr(vis, "kind", None) == "texture":
        mat = vis.material
        img = getattr(mat, "baseColorTexture", None) or getattr(mat, "image", None)
        factor = getattr(mat, "baseColorFactor", None)
        if factor is None:
            factor = getattr(mat, "diffuse", None)
        f = np.asarray(factor, float)[:4] / 255.0 if factor is not None else np.ones(4)
        uv = getattr(vis, "uv", None)
        if img is not None and uv is not None and len(uv) == len(m.vertices):
            px = _pixels(img)
            if np.any(f[:3] < 0.99):
                px = (px * f[:3]).astype(np.uint8)
            out.uv, out.image, out.texture = np.asarray(uv, float), px, where
        else:
            out.rgba = tuple(float(x) for x in np.r_[f[:3], 1.0])
    elif getattr(vis, "kind", None) in ("vertex", "face"):
        c = np.asarray(vis.vertex_colors if vis.kind == "vertex" else vis.face_colors, float)[:, :4] / 255.0
        out.rgba = tuple(float(x) for x in np.r_[c[:, :3].mean(axis=0), 1.0])
    return out


def load_visuals(path: Path) -> list[VisualMesh]:
    """Every drawn sub-mesh of a file, with transforms of a scene graph applied."""
    suffix = path.suffix.lower()
    if suffix in USD_SUFFIXES:
        from refspatial_gen.assets.usd_mesh import load_usd_visuals

        return load_usd_visuals(path)
    if suffix not in MESH_SUFFIXES:
        raise ValueError(f"{path}: unsupported mesh format {suffix} (use {', '.join(MESH_SUFFIXES + USD_SUFFIXES)})")
    # MTL files often name textures in a sibling folder (`../../textures/x.png`); trimesh 5 refuses paths
    # outside the mesh's folder unless asked, and would silently drop the texture.
    resolver = trimesh.resolvers.FilePathResolver(str(path), allow_anywhere=True)
    loaded = trimesh.load(str(path), process=False, maintain_order=True, resolver=resolver)
    meshes = loaded.dump(concatenate=False) if isinstance(loaded, trimesh.Scene) else [loaded]
    out = [
        _look(m, f"{path}#{i}" if len(meshes) > 1 else str(path))
        for i, m in enumerate(meshes)
        if isinstance(m, trimesh.Trimesh) and len(m.faces)
    ]
    if not out:
        raise ValueError(f"{path}: no triangle meshes")
    return out


def load_mesh_file(path: Path) -> trimesh.Trimesh:
    """Any supported mesh file -> one Trimesh (geometry only; sub-meshes concatenated)."""
    vs = load_visuals(Path(path))
    return trimesh.util.concatenate([v.mesh for v in vs]) if len(vs) > 1 else vs[0].mesh


def _external_texture(v: VisualMesh, texture: str) -> None:
    """A catalog `texture:` replaces the embedded one (only where the mesh has UVs)."""
    from PIL import Image

    if v.uv is not None:
        v.image, v.texture = _pixels(Image.open(texture)), texture


@lru_cache(maxsize=64)
def _external_geometry(
    mesh: str,
    collision: str,
    texture: str,
    scale: float,
    up: str,
    parts: tuple[tuple[str, tuple | None], ...],
    rgba: tuple | None,
    mass: float,
) -> AssetGeometry:
    if parts:
        visuals = []
        for f, col in parts:
            for v in load_visuals(Path(f)):
                v.rgba = col if col is not None else v.rgba
                visuals.append(v)
    else:
        visuals = load_visuals(Path(mesh))
    R = up_rotation(up) * scale
    pts = np.concatenate([np.asarray(v.mesh.vertices) for v in visuals]) @ R.T
    lo, hi = pts.min(axis=0), pts.max(axis=0)
    offset = -np.array([(lo[0] + hi[0]) / 2, (lo[1] + hi[1]) / 2, lo[2]])

    def place(m: trimesh.Trimesh) -> trimesh.Trimesh:
        return trimesh.Trimesh(np.asarray(m.vertices, float) @ R.T + offset, np.asarray(m.faces), process=False)

    out = []
    for v in visuals:
        if texture:
            _external_texture(v, texture)
        col = v.rgba if v.rgba is not None else rgba
        out.append(
            Part(
                "mesh",
                mesh=place(v.mesh),
                uv=v.uv,
                texture=v.texture if v.image is not None else None,
                texture_img=v.image,
                rgba=col,
                collide=False,
            )
        )
    if collision == "hull":
        hull = trimesh.Trimesh(pts + offset, process=False).convex_hull
        out.append(Part("mesh", mesh=hull, visual=False))
    else:
        files = sorted(Path(collision).glob("*.stl"), key=lambda p: (len(p.name), p.name))
        if not files:
            raise FileNotFoundError(f"{collision}: no convex collision parts (*.stl)")
        out += [
            Part("mesh", mesh=place(trimesh.load(str(f), force="mesh", process=False)), visual=False) for f in files
        ]
    geo = AssetGeometry(out, density=DEFAULT_DENSITY)
    if mass > 0:
        vol = sum(abs(p.trimesh().convex_hull.volume) for p in out if p.collide)
        geo.density = mass / max(vol, 1e-9)
    return geo


def external_available(cat: Category) -> bool:
    """Whether the category's mesh resolved (the catalog loader already reports missing files as errors)."""
    return bool(cat.external.get("mesh")) and Path(cat.external["mesh"]).exists()


def build_external(cat: Category) -> AssetGeometry:
    """The geometry of an external category (shared, cached: callers must not mutate it)."""
    e = cat.external
    parts = tuple((p["mesh"], p.get("rgba")) for p in e.get("parts") or ())
    try:
        return _external_geometry(
            str(e["mesh"]),
            str(e.get("collision", "hull")),
            str(e.get("texture") or ""),
            float(e.get("scale", 1.0)),
            str(e.get("up", "z")),
            parts,
            e.get("rgba"),
            float(e.get("mass", 0.0) or 0.0),
        )
    except (FileNotFoundError, ValueError, OSError) as err:
        raise DropUnit("asset_unreadable", f"{cat.name}: {err}") from err
