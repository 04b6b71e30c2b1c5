"""Scene lights as RefSpatial randomises them: 1-3 lights, each at 0.6-1.4x a base intensity.

A key light (a directional "window" light or a ceiling spot) may cast shadows; the others are ceiling
spots that fill. Lights are plain data (`Light`) so any renderer (MuJoCo here, Blender later) draws
the same ones.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

import numpy as np

KEY_BASE, FILL_BASE = 0.55, 0.3  # diffuse intensity of a 1.0x key / fill light (MuJoCo units, 0..1)


@dataclass
class Light:
    """One light: `kind` "directional" (only `direction` matters) or "spot" (at `pos`, aimed along `direction`)."""

    kind: str
    pos: np.ndarray
    direction: np.ndarray  # unit vector the light travels along
    color: np.ndarray  # rgb 0..1 (warmth), multiplied by intensity * base
    intensity: float  # RefSpatial's multiplier (0.6-1.4 by default)
    base: float  # diffuse level of a 1.0x light
    shadow: bool
    cutoff_deg: float = 70.0  # spot cone half-angle

    def diffuse(self) -> np.ndarray:
        return np.clip(self.color * self.base * self.intensity, 0, 1)

    def to_json(self) -> dict[str, Any]:
        return {
            "kind": self.kind,
            "pos": [float(x) for x in self.pos],
            "direction": [float(x) for x in self.direction],
            "color": [float(x) for x in self.color],
            "intensity": float(self.intensity),
            "base": self.base,
            "diffuse": [float(x) for x in self.diffuse()],
            "shadow": self.shadow,
            "cutoff_deg": self.cutoff_deg,
        }


def _unit(v) -> np.ndarray:
    v = np.asarray(v, float)
    return v / np.linalg.norm(v)


def sample_lights(
    rng: np.random.Generator, cfg: dict[str, Any], target: np.ndarray, room_half: np.ndarray
) -> list[Light]:
    """1..3 lights around `target` (the middle of the objects); intensities from `light_intensity`."""
    lo_n, hi_n = (int(x) for x in cfg.get("lights", [1, 3]))
    lo_i, hi_i = (float(x) for x in cfg.get("light_intensity", [0.6, 1.4]))
    n = int(rng.integers(lo_n, hi_n + 1))
    shadows = bool(cfg.get("shadows", True))
    out = []
    for k in range(n):
        warm = np.array([1.0, rng.uniform(0.9, 1.0), rng.uniform(0.78, 0.98)])
        inten = float(rng.uniform(lo_i, hi_i))
        if k == 0 and rng.random() < 0.6:  # daylight through a window: directional, from above at 35-70 degrees
            elev, az = np.deg2rad(rng.uniform(35, 70)), rng.uniform(-np.pi, np.pi)
            d = -_unit([np.cos(elev) * np.cos(az), np.cos(elev) * np.sin(az), np.sin(elev)])
            out.append(Light("directional", np.asarray(target) - 3 * d, d, warm, inten, KEY_BASE, shadows))
            continue
        pos = np.array(
            [rng.uniform(-0.8, 0.8) * room_half[0], rng.uniform(-0.8, 0.8) * room_half[1], rng.uniform(2.3, 2.7)]
        )
        if k == 0:
            pos[:2] = np.asarray(target)[:2] + rng.normal(0, 0.5, 2)
        d = _unit(np.asarray(target, float) + np.r_[rng.normal(0, 0.3, 2), 0.0] - pos)
        out.append(
            Light(
                "spot",
                pos,
                d,
                warm,
                inten,
                KEY_BASE if k == 0 else FILL_BASE,
                shadows and k == 0,
                float(rng.uniform(55, 80)),
            )
        )
    return out
