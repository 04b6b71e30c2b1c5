"""A settled scene, and its renderer-neutral description (what a second renderer, e.g. Blender, draws).

`SettledScene` is what `generate` hands to the renderer chosen by name (`renderer:` in the recipe, see
renderers.py): the layout (`desc`), the settled MuJoCo model (`sim`) and the catalog's colours and
materials. MuJoCo renders straight from `sim`; any other renderer calls `describe(cams)` and draws the
`RenderScene`: every drawn mesh with its world pose and instance id, its look (colour, material
parameters, texture pixels with authored UVs or a tiled procedural texture), the lights, and the
cameras with intrinsics. Instance ids are the same as MuJoCo's segmentation (object index + 1, 0 for
room and furniture), so masks and depth of two renderers can be compared per pixel.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from refspatial_gen.core.camera import Camera
from refspatial_gen.sources.sim.layout import SceneDesc
from refspatial_gen.sources.sim.looks import Look, floor_look, furniture_look, part_look
from refspatial_gen.sources.sim.model import SimModel, room_statics


@dataclass
class MeshItem:
    """One drawn mesh. `vertices` are metres in the item's local frame; `world_from_local` places it.
    `uv` is per vertex: authored UVs (look.repeat None) or metres along each face (tiled looks)."""

    name: str
    instance_id: int  # object index + 1; 0 = room and furniture
    vertices: np.ndarray  # (N, 3) float
    faces: np.ndarray  # (M, 3) int
    uv: np.ndarray | None
    world_from_local: np.ndarray  # 4x4
    look: Look


@dataclass
class RenderScene:
    meshes: list[MeshItem]
    lights: list[dict[str, Any]]
    cameras: list[Camera]
    ambient: float
    meta: dict[str, Any] = field(default_factory=dict)

    def save(self, folder: str | Path) -> Path:
        """scene.json (meshes' poses and looks, lights, cameras), meshes.npz (arrays), textures/*.png."""
        from PIL import Image

        folder = Path(folder)
        (folder / "textures").mkdir(parents=True, exist_ok=True)
        arrays, items, tex_files = {}, [], {}
        for i, m in enumerate(self.meshes):
            arrays[f"v{i}"], arrays[f"f{i}"] = m.vertices.astype(np.float32), m.faces.astype(np.int32)
            if m.uv is not None:
                arrays[f"uv{i}"] = m.uv.astype(np.float32)
            look = m.look.to_json()
            if m.look.texture is not None:
                key = m.look.texture_key or f"img{id(m.look.texture)}"
                if key not in tex_files:
                    tex_files[key] = f"textures/t{len(tex_files):03d}.png"
                    Image.fromarray(np.asarray(m.look.texture)).save(folder / tex_files[key])
                look["texture_file"] = tex_files[key]
            items.append(
                {
                    "name": m.name,
                    "instance_id": m.instance_id,
                    "arrays": i,
                    "has_uv": m.uv is not None,
                    "world_from_local": m.world_from_local.tolist(),
                    "look": look,
                }
            )
        np.savez_compressed(folder / "meshes.npz", **arrays)
        import json

        doc = {
            "schema": "refspatial-render-scene/1",
            "units": "metres, z up; cameras OpenCV (x right, y down, z forward)",
            "meshes": items,
            "lights": self.lights,
            "ambient": self.ambient,
            "meta": self.meta,
            "cameras": [c.to_json() for c in self.cameras],
        }
        (folder / "scene.json").write_text(json.dumps(doc, indent=1))
        return folder


def _box_mesh(half: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """A box as 24 vertices (4 per face) with UVs in metres along each face, for tiled textures."""
    import trimesh

    m = trimesh.creation.box(extents=2 * np.asarray(half, float))
    tri = m.triangles.reshape(-1, 3)
    normals = np.repeat(m.face_normals, 3, axis=0)
    ax = np.abs(normals).argmax(axis=1)
    uv = np.where(ax[:, None] == 0, tri[:, [1, 2]], np.where(ax[:, None] == 1, tri[:, [0, 2]], tri[:, [0, 1]]))
    return tri, np.arange(len(tri)).reshape(-1, 3), uv


def _pose(R: np.ndarray, p: np.ndarray) -> np.ndarray:
    T = np.eye(4)
    T[:3, :3], T[:3, 3] = R, p
    return T


@dataclass
class SettledScene:
    desc: SceneDesc
    sim: SimModel
    colors: dict[str, tuple[float, float, float]]
    materials: dict[str, dict[str, float]]

    def describe(self, cams: list[Camera]) -> RenderScene:
        """The renderer-neutral description of this scene seen by `cams`."""
        from refspatial_gen.sources.sim.physics import body_pose

        ap, items = self.desc.appearance, []
        if self.desc.floor:
            hx, hy = self.desc.room_half + 2
            v = np.array([[-hx, -hy, 0], [hx, -hy, 0], [hx, hy, 0], [-hx, hy, 0]], float)
            items.append(
                MeshItem("floor", 0, v, np.array([[0, 1, 2], [0, 2, 3]]), v[:, :2].copy(), np.eye(4), floor_look(ap))
            )
        for sb in room_statics(self.desc):
            v, f, uv = _box_mesh(sb.half)
            items.append(MeshItem(sb.name, 0, v, f, uv, _pose(np.eye(3), sb.center), furniture_look(sb.look, ap)))
        for k, o in enumerate(self.desc.objects):
            p, R = body_pose(self.sim, k)
            for j, part in enumerate(o.geometry.parts):
                if not part.visual:
                    continue
                tm = part.trimesh()
                uv = part.uv if (part.uv is not None and part.kind == "mesh") else None
                items.append(
                    MeshItem(
                        f"{o.key}_g{j}",
                        k + 1,
                        np.asarray(tm.vertices, float),
                        np.asarray(tm.faces),
                        uv,
                        _pose(R, p),
                        part_look(o, part, self.colors, self.materials),
                    )
                )
        return RenderScene(
            items,
            [L.to_json() for L in self.desc.lights],
            cams,
            float(ap.get("ambient", 0.3)),
            {"layout": self.desc.kind, "n_objects": len(self.desc.objects)},
        )
