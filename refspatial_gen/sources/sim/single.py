"""One object alone, rendered from given cameras: asset contact sheets and texture checks.

Why a separate path: a sheet or a texture test must show the asset as the simulator draws it (same
materials, textures and renderer) without a room, physics or layout randomness around it.
"""

from __future__ import annotations

from typing import Any

import numpy as np

from refspatial_gen.assets import AssetGeometry, Category
from refspatial_gen.core.camera import Camera
from refspatial_gen.sources.sim.layout import PlacedObject, SceneDesc

NEUTRAL_LOOK: dict[str, Any] = {
    "table_tex": 3,
    "table_tint": np.array([0.8, 0.8, 0.8]),
    "floor_tex": 1,
    "floor_rgb1": np.array([0.5, 0.5, 0.5]),
    "wall_rgb": np.array([0.8, 0.8, 0.8]),
    "counter_rgb": np.array([0.6, 0.6, 0.6]),
    "cabinet_rgb": np.array([0.7, 0.6, 0.5]),
    "sofa_rgb": np.array([0.5, 0.5, 0.55]),
    "bedding_rgb": np.array([0.9, 0.9, 0.9]),
    "ambient": 0.35,
    "headlight": 0.3,
}


def neutral_lights() -> list:
    """A fixed key and fill light, so sheets and texture checks look the same every time."""
    from refspatial_gen.sources.sim.lighting import KEY_BASE, Light

    d = np.array([-0.3, -0.2, -1.0]) / np.linalg.norm([-0.3, -0.2, -1.0])
    return [
        Light("directional", -3 * d, d, np.ones(3), 1.0, KEY_BASE, False),
        Light("directional", np.array([0, 0, 3.0]), np.array([0.5, 0.4, -0.77]), np.ones(3), 0.6, KEY_BASE, False),
    ]


def single_object_desc(
    cat: Category, geo: AssetGeometry, rgb=(0.7, 0.7, 0.7), material: str = "plastic", floor: bool = False
) -> SceneDesc:
    """A scene holding only this object at the origin (bottom centre), unrotated."""
    rgb = np.asarray(rgb, float)
    o = PlacedObject(
        "o00", cat, geo, cat.colors[0] if cat.colors else "gray", rgb, rgb * 0.5, material, np.zeros(3), 0.0, "floor"
    )
    return SceneDesc(
        "single", [o], [], [], [], np.array([1.0, 1.0]), False, dict(NEUTRAL_LOOK), floor, neutral_lights()
    )


def render_single(
    desc: SceneDesc,
    cams: list[Camera],
    materials: dict[str, dict[str, float]],
    colors: dict[str, tuple[float, float, float]],
    cfg: dict[str, Any] | None = None,
):
    """RGB, depth and instance renders of a single-object scene (no physics step: the pose is as placed)."""
    from refspatial_gen.sources.sim.physics import build_model
    from refspatial_gen.sources.sim.render import render_views

    c = {"width": cams[0].width, "height": cams[0].height, "_colors": colors, **(cfg or {})}
    sim = build_model(desc, materials, c, len(cams))
    return render_views(sim, cams)
