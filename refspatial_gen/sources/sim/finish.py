"""Per-instance surface finish: each object's specular, shininess and reflectance drawn within its material's range.

Why: with one fixed value per material every mug shines alike; RefSpatial-style randomisation varies the
look of same-category objects. The ranges live in the catalog (`materials:` of assets/catalog.yaml: a
number, or [lo, hi]), so metal stays shinier than wood or cloth and nothing becomes a mirror. Values are
drawn from the unit's Generator in object order, three draws per object whatever the ranges, and rounded,
so a seed repeats byte for byte; the drawn finish is recorded in each object's provenance.
"""

from __future__ import annotations

from typing import Any

import numpy as np

FINISH_KEYS = ("specular", "shininess", "reflectance")
DEFAULTS = {"specular": 0.3, "shininess": 0.3, "reflectance": 0.0}  # looks.Look's defaults


def draw_finish(ranges: dict[str, tuple[float, float]], rng: np.random.Generator) -> dict[str, float]:
    """One instance's finish from its material's ranges (a missing key keeps its default)."""
    out = {}
    for k in FINISH_KEYS:
        lo, hi = ranges.get(k, (DEFAULTS[k], DEFAULTS[k]))
        out[k] = round(float(lo + (hi - lo) * rng.random()), 4)
    return out


def draw_finishes(
    objects: list[Any], material_ranges: dict[str, dict[str, tuple[float, float]]], rng: np.random.Generator
) -> None:
    """Set `o.finish` on every placed object, in order."""
    for o in objects:
        o.finish = draw_finish(material_ranges.get(o.material, {}), rng)
