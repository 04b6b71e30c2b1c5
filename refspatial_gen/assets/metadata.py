"""Per-asset metadata a folder already carries, read so that `assets import` asks for nothing else.

Understood: an `objects.json` in the folder (the shared `ycb_sim` and `object_sim` sets: category,
mesh, texture, shipped convex parts, per-part colours, mass), and Objaverse-style annotation JSON, either
a sidecar `<mesh stem>.json` or one `annotations.json` (a list, or a mapping from uid / file stem to a
record). Annotation keys (first one found wins):
  category | label | name          the category word used in questions
  front | front_vector | front_view  semantic front, a vector [x, y, z] in the mesh file's axes or "+x"/"-y"...
  front_phrase | phrase            how to say it ("the handle side")
  size | real_size | dimensions     real size in metres: the longest side, or [x, y, z] in the file's axes
  scale                             metres per mesh unit (instead of size)
  up | up_axis                      which file axis is up: z, y, x, -z, -y, -x
  colors, materials, mass           colour words, catalog materials, kilograms
Without any of this a mesh file is still imported: category from its folder or file name, up axis from
the format (glTF is y-up, USD says so, others z-up), scale from the category's size range.
"""

from __future__ import annotations

import json
import re
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from refspatial_gen.assets.external import MESH_SUFFIXES, USD_SUFFIXES

SKIP_DIRS = {"collision", "parts", "textures", "materials"}


@dataclass
class AssetRecord:
    name: str
    mesh: Path
    category: str
    texture: Path | None = None
    collision_dir: Path | None = None  # shipped convex parts
    parts: list[tuple[Path, tuple | None]] = field(default_factory=list)  # drawn parts with rgba
    rgba: tuple | None = None
    front: Any = None
    front_phrase: str | None = None
    size: Any = None
    scale: float | None = None
    up: str | None = None
    mass: float | None = None
    colors: list[str] | None = None
    materials: list[str] | None = None
    source: str = ""


def category_from_name(stem: str) -> str:
    """`003_cracker_box` -> "cracker box", `WaterBottle-2` -> "water bottle"."""
    s = re.sub(r"([a-z])([A-Z])", r"\1 \2", stem)
    s = re.sub(r"[_\-.]+", " ", s)
    s = re.sub(r"\b\d+\b", " ", s)
    return " ".join(s.lower().split()) or stem.lower()


def _first(d: dict, *keys: str) -> Any:
    for k in keys:
        if d.get(k) is not None:
            return d[k]
    return None


def _apply_annotation(r: AssetRecord, a: dict) -> None:
    r.category = str(_first(a, "category", "label") or r.category)
    r.front = _first(a, "front", "front_vector", "front_view")
    r.front_phrase = _first(a, "front_phrase", "phrase")
    r.size = _first(a, "size", "real_size", "dimensions")
    sc = a.get("scale")
    r.scale = float(sc) if isinstance(sc, (int, float)) else r.scale
    r.up = _first(a, "up", "up_axis") or r.up
    r.colors = a.get("colors") or r.colors
    r.materials = a.get("materials") or r.materials
    m = _first(a, "mass", "mass_kg")
    r.mass = float(m) if isinstance(m, (int, float)) else r.mass


def _objects_json(folder: Path) -> list[AssetRecord]:
    doc = json.loads((folder / "objects.json").read_text())
    out = []
    for o in doc.get("objects", doc if isinstance(doc, list) else []):
        files = o.get("files", {})
        mesh = files.get("mesh") or files.get("visual_mesh") or o.get("mesh")
        if not mesh:
            continue
        r = AssetRecord(
            str(o.get("name") or Path(mesh).stem),
            folder / mesh,
            str(o.get("category") or category_from_name(Path(mesh).stem)),
            source=f"{folder.name}/objects.json",
        )
        if files.get("texture"):
            r.texture = folder / files["texture"]
        parts = files.get("collision_convex_parts") or []
        if parts:
            r.collision_dir = (folder / parts[0]).parent
        geoms = files.get("mjcf_visual_geoms") or []
        if len(geoms) > 1:
            r.parts = [(folder / g["mesh"], tuple(g["rgba"]) if g.get("rgba") else None) for g in geoms]
        elif len(geoms) == 1 and geoms[0].get("rgba"):
            r.rgba = tuple(geoms[0]["rgba"])
        col = o.get("mjcf_collision_geom") or {}
        if isinstance(col.get("mass_kg"), (int, float)):
            r.mass = float(col["mass_kg"])
        if "units" in doc and "metre" in str(doc["units"]):
            r.scale = 1.0
        _apply_annotation(r, o.get("annotation") or {})
        out.append(r)
    return out


def _annotations(folder: Path) -> dict[str, dict]:
    p = folder / "annotations.json"
    if not p.exists():
        return {}
    doc = json.loads(p.read_text())
    if isinstance(doc, list):
        return {str(_first(a, "uid", "file", "mesh", "name")): a for a in doc if isinstance(a, dict)}
    return {str(k): v for k, v in doc.items() if isinstance(v, dict)}


def scan_folder(folder: Path) -> list[AssetRecord]:
    """Asset records of a folder: from its objects.json when present, else one per mesh file found."""
    folder = Path(folder)
    if (folder / "objects.json").exists():
        return _objects_json(folder)
    ann = _annotations(folder)
    out = []
    suffixes = MESH_SUFFIXES + USD_SUFFIXES
    for p in sorted(folder.rglob("*")):
        if (
            p.suffix.lower() not in suffixes
            or not p.is_file()
            or SKIP_DIRS & {q.lower() for q in p.relative_to(folder).parts[:-1]}
        ):
            continue
        rel = p.relative_to(folder)
        named = p.stem if p.stem.lower() not in ("model", "mesh", "textured", "scene") else p.parent.name
        r = AssetRecord(rel.with_suffix("").as_posix(), p, category_from_name(named), source=str(rel))
        side = p.with_suffix(".json")
        a = (
            json.loads(side.read_text())
            if side.exists()
            else (ann.get(p.stem) or ann.get(rel.as_posix()) or ann.get(p.name) or {})
        )
        if isinstance(a, dict):
            _apply_annotation(r, a)
        out.append(r)
    return out
