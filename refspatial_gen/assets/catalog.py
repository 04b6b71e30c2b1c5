"""The asset catalog: categories with size ranges, colours, materials and semantic fronts (assets/catalog.yaml).

Why a data file: recipe authors add or tune object categories without touching Python; errors in it are
reported as `file:line: message` like any recipe error. A catalog can `include:` others (`builtin` is
the package's own catalog) and extends them: its colours, materials and categories are added, a category
of the same name replaces the included one. Every path resolves relative to the file that names it
(see assets/paths.py), and every path is checked when the catalog loads, so a missing mesh is a recipe
error before any work, never a unit that silently drops.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from functools import lru_cache
from pathlib import Path
from typing import Any

import numpy as np

from refspatial_gen.assets.paths import REPO_ROOT, cache_root, missing_hint, resolve_path, shared_data_root
from refspatial_gen.core.errors import RecipeError, RecipeErrors
from refspatial_gen.yamlpos import line_of, load_yaml

DEFAULT_CATALOG = REPO_ROOT / "assets" / "catalog.yaml"
SCALES = ("tabletop", "room")
UP_AXES = ("z", "y", "x", "-z", "-y", "-x")
CATEGORY_KEYS = {
    "builder",
    "dims",
    "colors",
    "materials",
    "scale",
    "front",
    "front_phrase",
    "weight",
    "accent",
    "fits_inside",
    "external",
    "label",
}
MATERIAL_KEYS = {"specular", "shininess", "reflectance", "alpha"}
EXTERNAL_KEYS = {"mesh", "texture", "collision", "scale", "up", "parts", "rgba", "mass", "sha256", "source"}


@dataclass(frozen=True)
class Category:
    """One object category. `dims` maps builder parameters to [lo, hi] ranges (metres)."""

    name: str
    builder: str  # a key of shapes.BUILDERS, or "external"
    dims: dict[str, tuple[float, float]]
    colors: tuple[str, ...]
    materials: tuple[str, ...]
    scale: str = "tabletop"  # where it is placed: "tabletop" (on tables, shelves) or "room" (on the floor)
    front: tuple[float, float, float] | None = None  # object frame
    front_phrase: str | None = None
    weight: float = 1.0
    accent: tuple[str, ...] = ()
    fits_inside: bool = False  # small enough to be put inside containers
    external: dict[str, Any] = field(default_factory=dict)  # resolved absolute paths (mesh, texture, collision, parts)
    label: str = ""  # the category word used in text (defaults to the name)
    origin: tuple[str, int] = ("", 0)  # (file, line) that defines it: `assets set-front` edits there

    def sample_dims(self, rng: np.random.Generator) -> dict[str, float]:
        return {k: float(rng.uniform(lo, hi)) for k, (lo, hi) in sorted(self.dims.items())}


@dataclass(frozen=True)
class Catalog:
    path: str
    colors: dict[str, tuple[float, float, float]]
    materials: dict[str, dict[str, float]]  # nominal parameters (the middle of each range)
    categories: dict[str, Category]
    files: tuple[str, ...] = ()  # every file read (includes first)
    material_ranges: dict[str, dict[str, tuple[float, float]]] = field(default_factory=dict)  # per-instance draws

    def names(self, scale: str | None = None) -> list[str]:
        return sorted(n for n, c in self.categories.items() if scale is None or c.scale == scale)

    def external_names(self) -> list[str]:
        return sorted(n for n, c in self.categories.items() if c.builder == "external")


def resolve_external(path: str, base: Path | None = None) -> Path:
    """Kept for callers of the old API: a catalog path spec -> absolute path."""
    return resolve_path(path, base)


def _number(x: Any) -> bool:
    """A finite int/float (YAML booleans and NaN/inf are not numbers here)."""
    if not isinstance(x, (int, float)) or isinstance(x, bool):
        return False
    try:
        return math.isfinite(float(x))
    except OverflowError:  # an int beyond float range
        return False


def _floats(v, n: int | None = None) -> bool:
    return isinstance(v, list) and (n is None or len(v) == n) and all(_number(x) for x in v)


def _mapping(v: Any, c: _Ctx, where: tuple, what: str) -> dict:
    """`v` when it is a mapping (absent = empty); otherwise an error and an empty mapping."""
    if v is None:
        return {}
    if not isinstance(v, dict):
        c.err(where, f"{what} must be a mapping")
        return {}
    return v


def _names(v: Any, c: _Ctx, where: tuple, what: str) -> tuple[str, ...]:
    """A list of names (strings); anything else (a nested list, a number, a mapping) is an error."""
    if v is None:
        return ()
    if not isinstance(v, list) or not all(isinstance(x, str) for x in v):
        c.err(where, f"{what} must be a list of names, got {v!r}")
        return ()
    return tuple(v)


class _Ctx:
    """One file being parsed: where errors point and what paths resolve against."""

    def __init__(self, file: str, lines: dict, errors: list[RecipeError]):
        self.file, self.lines, self.errors, self.base = file, lines, errors, Path(file).resolve().parent
        self.reported: set[str] = set()

    def err(self, path: tuple, msg: str) -> None:
        self.errors.append(RecipeError(self.file, line_of(self.lines, path), msg))

    def path(self, spec: Any, where: tuple, what: str, want_dir: bool = False) -> str | None:
        """Resolve and check one path spec; None (and an error) when it is not there."""
        if not isinstance(spec, str) or not spec:
            self.err(where, f"{what} must be a path string")
            return None
        p = resolve_path(spec, self.base)
        for prefix, root in (("shared:", shared_data_root()), ("cache:", cache_root())):
            if spec.startswith(prefix) and not root.is_dir():  # one error for the root, not one per asset
                if prefix not in self.reported:
                    self.reported.add(prefix)
                    self.err(where, f"{what} {spec!r}: folder {root} does not exist{missing_hint(spec)}")
                return None
        ok = p.is_dir() if want_dir else p.is_file()
        if not ok:
            kind = "folder" if want_dir else "file"
            self.err(where, f"{what} {spec!r}: {kind} {p} not found{missing_hint(spec)}")
            return None
        return str(p)


def _external(name: str, ext: Any, c: _Ctx) -> dict[str, Any]:
    where = ("categories", name, "external")
    if not isinstance(ext, dict):
        c.err(where, f"category {name!r}: external must be a mapping")
        return {}
    for k in ext:
        if k not in EXTERNAL_KEYS:
            c.err(
                where + (k,),
                f"category {name!r}: unknown external key {k!r} (known: {', '.join(sorted(EXTERNAL_KEYS))})",
            )
    out: dict[str, Any] = {"spec": dict(ext)}
    if "mesh" not in ext:
        c.err(where, f"category {name!r}: external categories need external.mesh")
    else:
        out["mesh"] = c.path(ext["mesh"], where + ("mesh",), f"category {name!r}: mesh")
    if ext.get("texture"):
        out["texture"] = c.path(ext["texture"], where + ("texture",), f"category {name!r}: texture")
    col = ext.get("collision", "hull")
    out["collision"] = (
        "hull" if col == "hull" else c.path(col, where + ("collision",), f"category {name!r}: collision parts", True)
    )
    if out["collision"] and out["collision"] != "hull" and not list(Path(out["collision"]).glob("*.stl")):
        c.err(where + ("collision",), f"category {name!r}: no convex parts (*.stl) in {out['collision']}")
    s = ext.get("scale", 1.0)
    if not (_number(s) and s > 0):
        c.err(where + ("scale",), f"category {name!r}: scale must be a number > 0")
        s = 1.0
    out["scale"] = float(s)
    out["up"] = str(ext.get("up", "z"))
    if out["up"] not in UP_AXES:
        c.err(where + ("up",), f"category {name!r}: up must be one of {', '.join(UP_AXES)}")
    if ext.get("rgba") is not None and not _floats(ext["rgba"], 4):
        c.err(where + ("rgba",), f"category {name!r}: rgba must be [r, g, b, a] in 0..1")
    out["rgba"] = tuple(float(x) for x in ext["rgba"]) if _floats(ext.get("rgba"), 4) else None
    parts = []
    raw_parts = ext.get("parts") or []
    if not isinstance(raw_parts, list):
        c.err(where + ("parts",), f"category {name!r}: parts must be a list")
        raw_parts = []
    for i, p in enumerate(raw_parts):
        if not isinstance(p, dict) or "mesh" not in p:
            c.err(where + ("parts", i), f"category {name!r}: each part needs a mesh")
            continue
        rgba = p.get("rgba")
        if rgba is not None and not _floats(rgba, 4):
            c.err(where + ("parts", i), f"category {name!r}: part rgba must be [r, g, b, a]")
            rgba = None
        parts.append(
            {
                "mesh": c.path(p["mesh"], where + ("parts", i), f"category {name!r}: part mesh"),
                "rgba": None if rgba is None else tuple(float(x) for x in rgba),
            }
        )
    out["parts"] = parts
    m = ext.get("mass", 0.0)
    if not (_number(m) and m >= 0):
        c.err(where + ("mass",), f"category {name!r}: mass must be kilograms >= 0")
        m = 0.0
    out["mass"] = float(m)
    return out


def _parse_category(name: str, d: Any, c: _Ctx, colors: dict, materials: dict, builders: set[str]) -> Category | None:
    path = ("categories", name)
    n0 = len(c.errors)

    def err(msg: str, key: str | None = None) -> None:
        c.err(path + ((key,) if key else ()), f"category {name!r}: {msg}")

    if not isinstance(d, dict):
        err("must be a mapping")
        return None
    for k in d:
        if k not in CATEGORY_KEYS:
            err(f"unknown key {k!r} (known: {', '.join(sorted(CATEGORY_KEYS))})", k)
    builder = d.get("builder", "external" if "external" in d else None)
    if not isinstance(builder, str) or (builder not in builders and builder != "external"):
        err(f"unknown builder {builder!r} (known: {', '.join(sorted(builders))})", "builder")
    dims = {}
    for k, v in _mapping(d.get("dims"), c, path + ("dims",), f"category {name!r}: dims").items():
        if not _floats(v, 2) or v[0] > v[1] or v[0] < 0:
            err(f"dims.{k} must be [lo, hi] with 0 <= lo <= hi, got {v!r}", "dims")
        else:
            dims[str(k)] = (float(v[0]), float(v[1]))
    cols = _names(d.get("colors"), c, path + ("colors",), f"category {name!r}: colors")
    accent = _names(d.get("accent"), c, path + ("accent",), f"category {name!r}: accent")
    for col in cols + accent:
        if col not in colors:
            err(f"unknown colour {col!r} (add it under colors:)", "colors")
    mats = _names(d.get("materials"), c, path + ("materials",), f"category {name!r}: materials") or ("plastic",)
    for m in mats:
        if m not in materials:
            err(f"unknown material {m!r}", "materials")
    weight = d.get("weight", 1.0)
    if not (_number(weight) and weight >= 0):
        err("weight must be a number >= 0", "weight")
    for key in ("front_phrase", "label"):
        if d.get(key) is not None and not isinstance(d[key], str):
            err(f"{key} must be text", key)
    front = d.get("front")
    if front is not None:
        if not _floats(front, 3) or np.linalg.norm(front) < 1e-9:
            err("front must be a non-zero [x, y, z] vector", "front")
            front = None
        else:
            front = tuple(float(x) / float(np.linalg.norm(front)) for x in front)
            if not d.get("front_phrase"):
                err("a front needs a front_phrase", "front")
    scale = d.get("scale", "tabletop")
    if not isinstance(scale, str) or scale not in SCALES:
        err(f"scale must be one of {SCALES}", "scale")
    ext = _external(name, d["external"], c) if "external" in d else {}
    if builder == "external" and "external" not in d:
        err("external categories need external.mesh", "external")
    if not cols and not d.get("colors"):  # (a malformed list was reported above)
        err("needs at least one colour", "colors")
    if len(c.errors) > n0:
        return None
    return Category(
        name,
        builder,
        dims,
        cols,
        mats,
        scale,
        front,
        d.get("front_phrase"),
        float(weight),
        accent,
        bool(d.get("fits_inside", False)),
        ext,
        str(d.get("label") or name),
        (c.file, line_of(c.lines, path)),
    )


def _material(name: str, v: Any, c: _Ctx) -> dict[str, tuple[float, float]] | None:
    """One material: known MuJoCo-style parameters, each a number in 0..1 or a range [lo, hi] that every
    object instance draws its own value from (sources/sim/finish.py); a number is the range [x, x]."""
    if not isinstance(v, dict):
        c.err(("materials", name), f"material {name!r} must be a mapping")
        return None
    out = {}
    for k, x in v.items():
        rng = (x, x) if _number(x) else tuple(x) if _floats(x, 2) else None
        if k not in MATERIAL_KEYS:
            c.err(
                ("materials", name, k),
                f"material {name!r}: unknown key {k!r} (known: {', '.join(sorted(MATERIAL_KEYS))})",
            )
        elif rng is None or not 0 <= rng[0] <= rng[1] <= 1:
            c.err(
                ("materials", name, k),
                f"material {name!r}: {k} must be a number in 0..1 or [lo, hi] with 0 <= lo <= hi <= 1, got {x!r}",
            )
        else:
            out[str(k)] = (float(rng[0]), float(rng[1]))
    return out  # a bad value was reported; the name still counts as known (no second error)


def _load_file(file: str, stack: tuple[str, ...], errors: list[RecipeError], acc: dict) -> None:
    """Parse `file` (its includes first) into `acc` (colors, materials, raw categories, files)."""
    from refspatial_gen.assets.shapes import BUILDERS

    try:
        data, lines = load_yaml(file)
    except RecipeError as e:
        errors.append(e)
        return
    c = _Ctx(file, lines, errors)
    if not isinstance(data, dict):
        c.err((), "catalog must be a mapping with colors, materials and categories (and optionally include)")
        return
    for k in data:
        if k not in ("include", "colors", "materials", "categories"):
            c.err((k,), f"unknown top-level key {k!r} (known: include, colors, materials, categories)")
    inc = data.get("include") or []
    if not isinstance(inc, (str, list)):
        c.err(("include",), "include must be a path or a list of paths")
        inc = []
    for i, spec in enumerate([inc] if isinstance(inc, str) else inc):
        where = ("include",) if isinstance(inc, str) else ("include", i)
        target = str(DEFAULT_CATALOG) if spec == "builtin" else c.path(spec, where, "include")
        if target is None:
            continue
        if str(Path(target).resolve()) in stack:
            c.err(where, f"include cycle: {' -> '.join(stack + (target,))}")
            continue
        _load_file(target, stack + (str(Path(target).resolve()),), errors, acc)
    for k, v in _mapping(data.get("colors"), c, ("colors",), "colors").items():
        if not _floats(v, 3) or not all(0 <= x <= 1 for x in v):
            c.err(("colors", k), f"colour {k!r} must be [r, g, b] in 0..1")
        else:
            acc["colors"][str(k)] = tuple(float(x) for x in v)
    for k, v in _mapping(data.get("materials"), c, ("materials",), "materials").items():
        mat = _material(str(k), v, c)
        if mat is not None:
            acc["material_ranges"][str(k)] = mat
    for name, d in _mapping(data.get("categories"), c, ("categories",), "categories").items():
        cat = _parse_category(str(name), d, c, acc["colors"], acc["material_ranges"], set(BUILDERS))
        if cat is not None:
            acc["categories"][str(name)] = cat
    acc["files"].append(file)


@lru_cache(maxsize=16)
def _load(files: tuple[str, ...], _key: tuple) -> Catalog:
    errors: list[RecipeError] = []
    acc: dict[str, Any] = {"colors": {}, "material_ranges": {}, "categories": {}, "files": []}
    for f in files:
        _load_file(f, (str(Path(f).resolve()),), errors, acc)
    if not acc["categories"] and not errors:
        errors.append(RecipeError(files[-1], 1, "catalog has no categories"))
    if errors:
        raise errors[0] if len(errors) == 1 else RecipeErrors(errors)
    ranges = acc["material_ranges"]
    nominal = {m: {k: round((lo + hi) / 2, 6) for k, (lo, hi) in r.items()} for m, r in ranges.items()}
    return Catalog(
        files[-1], acc["colors"], nominal, dict(sorted(acc["categories"].items())), tuple(acc["files"]), ranges
    )


def load_catalog(path: str | list[str] | tuple[str, ...] | None = None) -> Catalog:
    """Load and check one catalog, or several merged in order (cached per process and data roots).

    Raises RecipeError / RecipeErrors naming file and line for every problem, missing files included.
    """
    if not path:
        files: tuple[str, ...] = (str(DEFAULT_CATALOG),)
    elif isinstance(path, (list, tuple)):
        files = tuple(str(p) for p in path)
    else:
        files = (str(path),)
    stamps = tuple(Path(f).stat().st_mtime_ns if Path(f).exists() else 0 for f in files)  # edits (set-front) reload
    return _load(files, (str(shared_data_root()), str(cache_root()), stamps))
