"""What every drawn surface looks like, decided once for all renderers: colour, material and texture.

Why one place: the MuJoCo model and the renderer-neutral scene description (for Blender) must draw the
same thing. Procedural textures (wood grain, laminate, checker, fabric) are generated here as pixels,
tiled by world size (`repeat`); textures of imported meshes keep their authored UVs (`repeat` None).
"""

from __future__ import annotations

from dataclasses import dataclass
from functools import lru_cache
from typing import Any

import numpy as np


@dataclass
class Look:
    rgba: tuple[float, float, float, float]  # base colour; multiplies the texture when there is one
    specular: float = 0.3
    shininess: float = 0.3
    reflectance: float = 0.0
    texture: np.ndarray | None = None  # uint8 HxWx3, first row = top of the image
    texture_key: str | None = None  # stable name (dedupe across parts; file path for imported textures)
    repeat: tuple[float, float] | None = None  # tiles per metre (procedural) or None (mesh UVs)

    def to_json(self) -> dict[str, Any]:
        return {
            "rgba": [float(x) for x in self.rgba],
            "specular": self.specular,
            "shininess": self.shininess,
            "reflectance": self.reflectance,
            "texture": self.texture_key,
            "repeat": None if self.repeat is None else list(self.repeat),
        }


@lru_cache(maxsize=16)
def procedural_texture(kind: str, variant: int, size: int = 256) -> np.ndarray:
    """Deterministic tileable-ish textures: wood grain (0-2), speckled laminate (3), checker, fabric weave."""
    r = np.random.default_rng(1000 + variant + 17 * len(kind))
    y, x = np.mgrid[0:size, 0:size] / size
    if kind == "checker":
        v = 0.82 + 0.18 * (((x * 8).astype(int) + (y * 8).astype(int)) % 2)
        img = np.stack([v, v, v], -1)
    elif kind == "fabric":
        weave = 0.9 + 0.04 * np.sin(2 * np.pi * x * 16) * np.sin(2 * np.pi * y * 16) + 0.05 * r.random((size, size))
        img = np.stack([weave] * 3, -1)
    elif variant % 4 == 3:
        base = 0.8 + 0.12 * r.random((size, size))
        img = np.stack([base, base * 0.98, base * 0.95], -1)
    else:  # grain along x: fine lines whose phase drifts slowly, plus plank seams
        drift = np.cumsum(r.normal(0, 1, size)) / size * 0.6
        lines = np.sin(
            2 * np.pi * (y * [60, 90, 45][variant % 3] + drift[None, :] * 4 + 0.3 * np.sin(2 * np.pi * x * 2))
        )
        fine = r.random((size, 1)) * 0.15 + r.random((size, size)) * 0.04
        planks = ((y * 4) % 1.0 < 0.012).astype(float) * 0.25
        v = 0.78 + 0.07 * lines + fine - planks
        img = np.stack([v, v * 0.8, v * 0.6], -1)
    out = (np.clip(img, 0, 1) * 255).astype(np.uint8)
    out.flags.writeable = False
    return out


def _tex(kind: str, variant: int, rgb, repeat, **params) -> Look:
    return Look(
        (*map(float, rgb), 1.0),
        texture=procedural_texture(kind, variant),
        texture_key=f"{kind}{variant}",
        repeat=repeat,
        **params,
    )


def furniture_look(look: str, ap: dict[str, Any]) -> Look:
    """Furniture and room surfaces by their look key (see layout.StaticBox.look)."""
    if look == "table":
        return _tex("wood", ap["table_tex"], ap["table_tint"], (1.2, 1.2), specular=0.3, shininess=0.4)
    if look == "shelf":
        return _tex("wood", ap["table_tex"], np.asarray(ap["table_tint"]) * 0.8, (1.0, 1.0), specular=0.2)
    if look == "cabinet":
        return _tex("wood", 3, ap["cabinet_rgb"], (1.0, 1.0), specular=0.3)
    if look in ("sofa", "bedding"):
        return _tex(
            "fabric",
            0,
            ap["sofa_rgb"] if look == "sofa" else ap["bedding_rgb"],
            (1.5, 1.5),
            specular=0.02,
            shininess=0.05,
        )
    if look == "counter":
        return Look((*map(float, ap["counter_rgb"]), 1.0), specular=0.4)
    if look == "wall":
        return Look((*map(float, ap["wall_rgb"]), 1.0), specular=0.05)
    return Look((0.25, 0.22, 0.2, 1.0), specular=0.3)  # legs, frames


def floor_look(ap: dict[str, Any]) -> Look:
    if ap["floor_tex"] == 0:
        return _tex("checker", 0, ap["floor_rgb1"], (0.6, 0.6), specular=0.1)
    return _tex("wood", (ap["floor_tex"] + 1) % 3, np.asarray(ap["floor_rgb1"]) * 0.6 + 0.3, (0.7, 0.7), specular=0.2)


def part_look(o, part, colors: dict, materials: dict) -> Look:
    """An object's part: its texture or authored colour if it has one, else the instance colour by role."""
    mp = materials[o.material]
    fin = getattr(o, "finish", None) or {}  # the instance's drawn finish, else the material's nominal values
    params = {
        k: float(fin.get(k, mp.get(k, d))) for k, d in (("specular", 0.3), ("shininess", 0.3), ("reflectance", 0.0))
    }
    if part.texture_img is not None:
        return Look(
            (1.0, 1.0, 1.0, 1.0),
            texture=part.texture_img,
            texture_key=part.texture or f"img{id(part.texture_img)}",
            **params,
        )
    if part.rgba is not None:
        return Look(tuple(float(x) for x in part.rgba[:3]) + (1.0,), **params)
    rgb = (
        o.rgb
        if part.role == "body"
        else o.accent_rgb
        if part.role == "accent"
        else colors.get(part.role, (0.5, 0.5, 0.5))
    )
    return Look((*map(float, rgb), float(mp.get("alpha", 1.0))), **params)
