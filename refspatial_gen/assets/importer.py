"""`refspatial-gen assets import DIR... --out my_catalog.yaml`: a catalog of a folder's meshes in one command.

For every mesh (see metadata.py for what is read): the up axis and scale (metadata, else the format's
convention and the category's size range in the built-in catalog), colour words from its texture or
colour, materials from the built-in category of the same name, collision from shipped convex parts or
CoACD (cached by mesh hash), and textures kept as authored. The written catalog `include:`s the
built-in one, so it extends it; its paths are relative to itself (or `shared:` / `cache:`).
"""

from __future__ import annotations

from pathlib import Path
from typing import Any

import numpy as np
import yaml

from refspatial_gen.assets.catalog import DEFAULT_CATALOG, load_catalog
from refspatial_gen.assets.external import load_visuals, up_rotation
from refspatial_gen.assets.metadata import AssetRecord, scan_folder
from refspatial_gen.assets.paths import cache_root, portable_spec

AXES = {
    "+x": [1, 0, 0],
    "-x": [-1, 0, 0],
    "+y": [0, 1, 0],
    "-y": [0, -1, 0],
    "+z": [0, 0, 1],
    "-z": [0, 0, -1],
    "x": [1, 0, 0],
    "y": [0, 1, 0],
    "z": [0, 0, 1],
}
UNIT_SCALES = (1.0, 0.01, 0.001)  # metres, centimetres, millimetres
GENERAL_RANGE = (0.03, 1.2)  # longest side of a household object, metres
FIXED_COLOURS = {"screen", "paper", "picture"}
DEFAULT_COLOURS = ["white", "gray", "blue", "red", "green", "yellow", "black"]
MATERIAL_WORDS = {
    "box": "cardboard",
    "carton": "cardboard",
    "can": "metal",
    "tin": "metal",
    "hammer": "metal",
    "bottle": "plastic",
    "mug": "ceramic",
    "cup": "ceramic",
    "bowl": "ceramic",
    "plate": "ceramic",
    "teapot": "ceramic",
    "glass": "glass",
    "apple": "organic",
    "fruit": "organic",
    "banana": "organic",
    "lemon": "organic",
    "bread": "organic",
    "book": "paper",
    "pillow": "fabric",
    "wood": "wood",
}


def guess_materials(label: str) -> list[str]:
    """Catalog materials from the category words ("tomato soup can" -> metal), plastic otherwise."""
    for w in reversed(label.split()):
        for key, mat in MATERIAL_WORDS.items():
            if w.startswith(key) or w.endswith(key):
                return [mat]
    return ["plastic"]


def parse_axis(v: Any) -> np.ndarray | None:
    """ "+x" / "-y" / [x, y, z] -> unit vector (None if unusable)."""
    if isinstance(v, str):
        v = AXES.get(v.strip().lower())
    try:
        a = np.asarray(v, float).reshape(3)
    except (TypeError, ValueError):
        return None
    n = float(np.linalg.norm(a))
    return a / n if n > 1e-9 else None


def size_range(label: str) -> tuple[float, float] | None:
    """Longest-side range (metres) of the built-in category with this name, from its dims at lo and hi."""
    from refspatial_gen.assets import build_geometry

    cat = load_catalog().categories.get(label)
    if cat is None or cat.builder == "external" or not cat.dims:
        return None
    rng = np.random.default_rng(0)
    sides = []
    for end in (0, 1):
        lo, hi = build_geometry(cat, {k: v[end] for k, v in cat.dims.items()}, rng).bounds()
        sides.append(float((hi - lo).max()))
    return min(sides), max(sides)


def infer_scale(longest: float, rng: tuple[float, float] | None) -> float:
    """The unit scale (m, cm, mm) that puts the longest side nearest (in log) to the range."""
    lo, hi = rng or GENERAL_RANGE
    mid = np.sqrt(lo * hi)
    return min(UNIT_SCALES, key=lambda s: abs(np.log(max(longest * s, 1e-9) / mid)))


def _colour_space(rgb: np.ndarray) -> np.ndarray:
    """Hue-and-saturation first, brightness second: rgb / max(rgb) plus a weighted brightness, so a dark
    red (0.4, 0, 0) is "red", not "brown", while grey levels still separate black, gray and white."""
    m = rgb.max(axis=-1, keepdims=True)
    return np.concatenate([rgb / np.maximum(m, 0.05), 0.8 * m], axis=-1)


def colour_words(visuals, palette: dict[str, tuple]) -> list[str]:
    """Colour words of an asset: the most frequent palette colours of its texture (atlas padding ignored)
    or its authored colour; [] when it has neither (the instance colour is then randomised)."""
    names = [n for n in palette if n not in FIXED_COLOURS]
    P = _colour_space(np.array([palette[n] for n in names]))
    px = []
    for v in visuals:
        if v.image is not None:
            im = (
                np.asarray(v.image, float)[
                    :: max(1, v.image.shape[0] // 64), :: max(1, v.image.shape[1] // 64)
                ].reshape(-1, 3)
                / 255
            )
            px.append(im[im.max(axis=1) > 0.04])
        elif v.rgba is not None:
            px.append(np.tile(np.asarray(v.rgba[:3], float), (200, 1)))
    if not px:
        return []
    allpx = np.concatenate(px)
    idx = np.argmin(((_colour_space(allpx)[:, None, :] - P[None]) ** 2).sum(-1), axis=1)
    counts = np.bincount(idx, minlength=len(names))
    order = [i for i in np.argsort(-counts, kind="stable") if counts[i] >= 0.2 * counts.max()]
    return [names[i] for i in order[:2]]


def _entry(r: AssetRecord, out_dir: Path, cache: Path, collision: str, builtin) -> tuple[str, dict[str, Any], dict]:
    visuals = []
    for p, col in r.parts or [(r.mesh, r.rgba)]:
        for v in load_visuals(p):
            v.rgba = tuple(col) if col is not None else v.rgba
            visuals.append(v)
    ext = r.mesh.suffix.lower()
    up = str(r.up or ("y" if ext in (".glb", ".gltf") else "z"))
    R = up_rotation(up)
    raw = np.concatenate([np.asarray(v.mesh.vertices) for v in visuals])
    extent = np.ptp(raw @ R.T, axis=0)
    label = r.category
    size = r.size
    if r.scale:
        scale = float(r.scale)
    elif isinstance(size, (int, float)) or (isinstance(size, list) and len(size) == 3):
        scale = float(max(size) if isinstance(size, list) else size) / float(extent.max())
    else:
        scale = infer_scale(float(extent.max()), size_range(label))
    dims = extent * scale
    base = builtin.categories.get(label)
    e: dict[str, Any] = {"mesh": portable_spec(r.mesh, out_dir)}
    if r.texture:
        e["texture"] = portable_spec(r.texture, out_dir)
    if r.parts:
        e["parts"] = [
            {"mesh": portable_spec(p, out_dir), **({"rgba": [float(x) for x in c]} if c else {})} for p, c in r.parts
        ]
    if r.rgba:
        e["rgba"] = [float(x) for x in r.rgba]
    info = {"collision": "hull"}
    if collision != "hull" and r.collision_dir is not None and collision == "auto":
        e["collision"] = portable_spec(r.collision_dir, out_dir)
        info["collision"] = f"shipped ({len(list(r.collision_dir.glob('*.stl')))} parts)"
    elif collision in ("auto", "coacd"):
        import trimesh

        from refspatial_gen.assets.collision import decompose

        m = trimesh.util.concatenate([v.mesh for v in visuals]) if len(visuals) > 1 else visuals[0].mesh
        kind, folder = decompose(m, cache)
        if folder is not None:
            e["collision"] = portable_spec(folder, out_dir)
            info["collision"] = f"coacd ({len(list(folder.glob('*.stl')))} parts)"
        else:
            info["collision"] = "hull (nearly convex)"
    e.update({"scale": round(scale, 6), "up": up})
    if r.mass:
        e["mass"] = round(float(r.mass), 4)
    e["source"] = r.source
    cols = list(r.colors or colour_words(visuals, builtin.colors) or (list(base.colors) if base else DEFAULT_COLOURS))
    d: dict[str, Any] = {
        "builder": "external",
        "label": label,
        "colors": cols,
        "materials": list(r.materials or (base.materials if base else guess_materials(label))),
        "scale": "tabletop" if dims.max() < 0.7 else "room",
    }
    if dims.max() < 0.12:
        d["fits_inside"] = True
    front = parse_axis(r.front) if r.front is not None else None
    if front is not None:
        d["front"] = [round(float(x), 4) for x in R @ front]
        d["front_phrase"] = r.front_phrase or "the front"
    d["external"] = e
    info.update(
        {
            "label": label,
            "size_m": [round(float(x), 3) for x in dims],
            "textured": any(v.image is not None for v in visuals),
        }
    )
    return r.name, d, info


class _Dumper(yaml.SafeDumper):
    """Block mappings (one key per line, so `set-front` can edit lines) with short lists on one line."""


_Dumper.add_representer(list, lambda d, v: d.represent_sequence("tag:yaml.org,2002:seq", v, flow_style=True))


def import_assets(
    dirs: list[str | Path],
    out: str | Path,
    cache: str | Path | None = None,
    collision: str = "auto",
    include: str = "builtin",
    progress=None,
) -> list[dict[str, Any]]:
    """Write the catalog `out` for every asset in `dirs`; returns one summary row per asset."""
    out = Path(out).resolve()
    out.parent.mkdir(parents=True, exist_ok=True)
    cache = Path(cache) if cache else cache_root()
    builtin = load_catalog()
    cats: dict[str, Any] = {}
    rows = []
    for folder in dirs:
        folder = Path(folder).resolve()
        if not folder.is_dir():
            raise FileNotFoundError(f"{folder}: not a folder")
        records = scan_folder(folder)
        for r in records:
            name, d, info = _entry(r, out.parent, cache, collision, builtin)
            key = f"{folder.name} {name}".replace("/", " ")
            cats[key] = d
            rows.append({"name": key, **info})
            if progress:
                progress(rows[-1])
    inc = "builtin" if include == "builtin" else portable_spec(Path(include), out.parent)
    head = (
        f"# Written by `refspatial-gen assets import {' '.join(str(Path(d)) for d in dirs)}`; edit fronts with\n"
        '# `refspatial-gen assets set-front NAME +x "the handle side"` and check them with `assets sheet`.\n'
        "# Paths are relative to this file (shared: = $REFSPATIAL_SHARED_DATA, cache: = $REFSPATIAL_CACHE).\n"
    )
    body = yaml.dump({"include": [inc], "categories": cats}, Dumper=_Dumper, sort_keys=False, width=120)
    out.write_text(head + body)
    return rows


__all__ = ["import_assets", "infer_scale", "size_range", "colour_words", "parse_axis", "DEFAULT_CATALOG"]
