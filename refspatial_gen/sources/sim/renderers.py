"""Renderers of settled scenes, chosen by name in the recipe (`renderer: mujoco`).

A renderer is a class constructed with the sim config, with `name` and `render(scene: SettledScene,
cams) -> list[RenderOut]` (RGB, metric z-depth, instance ids = object index + 1). MuJoCo renders from the
compiled model; Blender (blender_render.py) draws `scene.describe(cams)`; each is one line here.
"""

from __future__ import annotations

import importlib
from typing import Protocol

from refspatial_gen.core.camera import Camera

# name -> "module:attribute" (imported lazily: a renderer's heavy dependency loads only when chosen)
RENDERERS: dict[str, str] = {
    "mujoco": "refspatial_gen.sources.sim.render:MujocoRenderer",
    "blender": "refspatial_gen.sources.sim.blender_render:BlenderRenderer",
}


class Renderer(Protocol):
    name: str

    def render(self, scene, cams: list[Camera]) -> list:
        """One RenderOut per camera."""
        ...


def renderer_names() -> list[str]:
    return sorted(RENDERERS)


def get_renderer(name: str, config: dict | None = None) -> Renderer:
    """The renderer called `name`, set up from the sim source's config (defaults when None)."""
    if name not in RENDERERS:
        raise KeyError(f"unknown renderer {name!r} (known: {', '.join(renderer_names())})")
    mod, attr = RENDERERS[name].split(":")
    return getattr(importlib.import_module(mod), attr)(config or {})
