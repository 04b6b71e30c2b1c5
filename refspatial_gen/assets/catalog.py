"""The asset catalog: categories with size ranges, colours, materials and semantic fronts (assets/catalog.yaml).

Why a data file: recipe authors add or tune object categories without touching Python; errors in it are
reported as `file:line: message` like any recipe error.
"""

from __future__ import annotations

import os
from dataclasses import dataclass, field
from functools import lru_cache
from pathlib import Path
from typing import Any

import numpy as np

from refspatial_gen.core.errors import RecipeError
from refspatial_gen.yamlpos import line_of, load_yaml

REPO_ROOT = Path(__file__).resolve().parents[2]
DEFAULT_CATALOG = REPO_ROOT / "assets" / "catalog.yaml"
SCALES = ("tabletop", "room")


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
    external: dict[str, Any] = field(default_factory=dict)  # mesh, collision, texture, scale for external meshes
    label: str = ""  # the category word used in text (defaults to the name)

    def sample_dims(self, rng: np.random.Generator) -> dict[str, float]:
        return {k: float(rng.uniform(lo, hi)) for k, (lo, hi) in sorted(self.dims.items())}


@dataclass(frozen=True)
class Catalog:
    path: str
    colors: dict[str, tuple[float, float, float]]
    materials: dict[str, dict[str, float]]
    categories: dict[str, Category]

    def names(self, scale: str | None = None) -> list[str]:
        return sorted(n for n, c in self.categories.items() if scale is None or c.scale == scale)


def shared_data_root() -> Path:
    """Where external meshes live: $REFSPATIAL_SHARED_DATA, else ../shared/data next to the repository."""
    env = os.environ.get("REFSPATIAL_SHARED_DATA")
    return Path(env) if env else REPO_ROOT.parent / "shared" / "data"


def resolve_external(path: str) -> Path:
    """`shared:ycb_sim/x/model.obj` -> under shared_data_root(); `$VAR/...` expanded; relative to the repo otherwise."""
    if path.startswith("shared:"):
        return shared_data_root() / path[len("shared:"):]
    p = Path(os.path.expandvars(path))
    return p if p.is_absolute() else REPO_ROOT / p


def _floats(v, n: int | None = None) -> bool:
    return isinstance(v, list) and (n is None or len(v) == n) and all(isinstance(x, (int, float)) and not isinstance(x, bool) for x in v)


def _parse_category(name: str, d: Any, file: str, lines: dict, colors: dict, materials: dict, builders: set[str]) -> Category:
    path = ("categories", name)

    def err(msg: str, key: str | None = None) -> RecipeError:
        return RecipeError(file, line_of(lines, path + ((key,) if key else ())), f"category {name!r}: {msg}")

    if not isinstance(d, dict):
        raise err("must be a mapping")
    known = {"builder", "dims", "colors", "materials", "scale", "front", "front_phrase", "weight", "accent", "fits_inside", "external", "label"}
    for k in d:
        if k not in known:
            raise err(f"unknown key {k!r} (known: {', '.join(sorted(known))})", k)
    builder = d.get("builder", "external" if "external" in d else None)
    if builder not in builders and builder != "external":
        raise err(f"unknown builder {builder!r} (known: {', '.join(sorted(builders))})", "builder")
    dims = {}
    for k, v in (d.get("dims") or {}).items():
        if not _floats(v, 2) or v[0] > v[1] or v[0] < 0:
            raise err(f"dims.{k} must be [lo, hi] with 0 <= lo <= hi, got {v!r}", "dims")
        dims[str(k)] = (float(v[0]), float(v[1]))
    cols = tuple(d.get("colors") or ())
    for c in cols + tuple(d.get("accent") or ()):
        if c not in colors:
            raise err(f"unknown colour {c!r} (add it under colors:)", "colors")
    mats = tuple(d.get("materials") or ("plastic",))
    for m in mats:
        if m not in materials:
            raise err(f"unknown material {m!r}", "materials")
    front = d.get("front")
    if front is not None:
        if not _floats(front, 3) or np.linalg.norm(front) < 1e-9:
            raise err("front must be a non-zero [x, y, z] vector", "front")
        front = tuple(float(x) / float(np.linalg.norm(front)) for x in front)
        if not d.get("front_phrase"):
            raise err("a front needs a front_phrase", "front")
    scale = d.get("scale", "tabletop")
    if scale not in SCALES:
        raise err(f"scale must be one of {SCALES}", "scale")
    ext = dict(d.get("external") or {})
    if builder == "external" and "mesh" not in ext:
        raise err("external categories need external.mesh", "external")
    if builder != "external" and not cols:
        raise err("needs at least one colour", "colors")
    return Category(name, builder, dims, cols, mats, scale, front, d.get("front_phrase"), float(d.get("weight", 1.0)),
                    tuple(d.get("accent") or ()), bool(d.get("fits_inside", False)), ext,
                    str(d.get("label") or name))


@lru_cache(maxsize=8)
def load_catalog(path: str | None = None) -> Catalog:
    """Load and check a catalog file (cached per process; the file is read-only data)."""
    from refspatial_gen.assets.shapes import BUILDERS

    file = str(path or DEFAULT_CATALOG)
    data, lines = load_yaml(file)
    if not isinstance(data, dict):
        raise RecipeError(file, 1, "catalog must be a mapping with colors, materials and categories")
    colors = {}
    for k, v in (data.get("colors") or {}).items():
        if not _floats(v, 3):
            raise RecipeError(file, line_of(lines, ("colors", k)), f"colour {k!r} must be [r, g, b] in 0..1")
        colors[str(k)] = tuple(float(x) for x in v)
    materials = {}
    for k, v in (data.get("materials") or {}).items():
        if not isinstance(v, dict):
            raise RecipeError(file, line_of(lines, ("materials", k)), f"material {k!r} must be a mapping")
        materials[str(k)] = {str(a): float(b) for a, b in v.items()}
    cats = {}
    for name, d in (data.get("categories") or {}).items():
        cats[str(name)] = _parse_category(str(name), d, file, lines, colors, materials, set(BUILDERS))
    if not cats:
        raise RecipeError(file, 1, "catalog has no categories")
    return Catalog(file, colors, materials, dict(sorted(cats.items())))
