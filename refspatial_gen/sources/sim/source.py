"""The simulated source: unit key -> random layout -> MuJoCo physics until at rest -> multi-view RGB-D frames."""

from __future__ import annotations

import time
from typing import Any

import numpy as np

from refspatial_gen.core.errors import DropUnit
from refspatial_gen.core.model import Frame
from refspatial_gen.schema import Field


def _weights_ok(v: Any) -> str | None:
    if not isinstance(v, dict) or not v:
        return "must map layout kinds to weights"
    from refspatial_gen.sources.sim.layout import LAYOUTS

    for k, w in v.items():
        if k not in LAYOUTS:
            return f"unknown layout {k!r} (known: {', '.join(sorted(LAYOUTS))})"
        if not isinstance(w, (int, float)) or w < 0:
            return f"weight of {k!r} must be a number >= 0"
    if sum(v.values()) <= 0:
        return "weights must not all be 0"
    return None


def _range_ok(v: Any) -> str | None:
    if not (isinstance(v, list) and len(v) == 2 and all(isinstance(x, (int, float)) for x in v) and 0 < v[0] <= v[1] < 170):
        return "must be [lo, hi] degrees with 0 < lo <= hi < 170"
    return None


CONFIG_FIELDS: dict[str, Field] = {
    "scenes": Field(int, default=10, min=1, doc="number of scenes when the run does not say"),
    "layouts": Field(dict, default={"tabletop": 0.7, "room": 0.3}, check=_weights_ok, doc="layout kind -> weight"),
    "min_objects": Field(int, default=3, min=1, max=30, doc="movable objects per scene, at least"),
    "max_objects": Field(int, default=12, min=1, max=30, doc="movable objects per scene, at most"),
    "width": Field(int, default=640, min=32, max=4096),
    "height": Field(int, default=480, min=32, max=4096),
    "views": Field(int, default=2, min=1, max=8, doc="cameras (frames) per scene"),
    "fovy_deg": Field(list, default=[45.0, 60.0], check=_range_ok, doc="vertical field of view range"),
    "view_spread_deg": Field(float, default=70.0, min=0, max=180, doc="azimuth step between views"),
    "catalog": Field(str, default="", doc="asset catalog YAML (default assets/catalog.yaml)"),
    "external_prob": Field(float, default=0.0, min=0, max=1, doc="chance that a tabletop object is an external mesh (YCB, ...)"),
    "repeat_prob": Field(float, default=0.3, min=0, max=1, doc="chance to repeat a category already in the scene"),
    "stack_prob": Field(float, default=0.25, min=0, max=1),
    "inside_prob": Field(float, default=0.3, min=0, max=1),
    "edge_prob": Field(float, default=0.3, min=0, max=1, doc="chance to place an object near an edge or corner"),
    "face_prob": Field(float, default=0.35, min=0, max=1, doc="chance that an object with a front faces another object"),
    "settle_max_steps": Field(int, default=3000, min=100, doc="physics step cap; unsettled scenes are dropped"),
    "settle_lin_vel": Field(float, default=0.005, min=0, doc="m/s: at rest below this"),
    "settle_ang_vel": Field(float, default=0.05, min=0, doc="rad/s: at rest below this"),
    "timestep": Field(float, default=0.002, min=0.0005, max=0.01),
    "shadow_size": Field(int, default=0, min=0, max=8192, doc="shadow map size; 0 = no shadows (fastest)"),
    "min_visible_objects": Field(int, default=2, min=0, doc="drop a view showing fewer objects"),
}


def defaults() -> dict[str, Any]:
    return {k: f.default for k, f in CONFIG_FIELDS.items()}


def _cfg(config: dict[str, Any]) -> dict[str, Any]:
    cfg = defaults()
    cfg.update({k: v for k, v in (config or {}).items() if v is not None})
    return cfg


def generate(unit_key: str, rng: np.random.Generator, config: dict[str, Any], timings: dict[str, float] | None = None,
             keep_scene: bool = False):
    """Frames for one scene (and, with keep_scene, the SceneDesc and settled SimModel for export)."""
    from refspatial_gen.assets import load_catalog
    from refspatial_gen.sources.sim.cameras import sample_cameras
    from refspatial_gen.sources.sim.frames import make_frames, scene_boxes
    from refspatial_gen.sources.sim.layout import LAYOUTS
    from refspatial_gen.sources.sim.physics import build_model, settle
    from refspatial_gen.sources.sim.render import render_views

    cfg = _cfg(config)
    t = timings if timings is not None else {}
    t0 = time.perf_counter()
    catalog = load_catalog(cfg["catalog"] or None)
    cfg["_colors"] = catalog.colors
    kinds = sorted(cfg["layouts"])
    w = np.array([float(cfg["layouts"][k]) for k in kinds])
    kind = kinds[int(rng.choice(len(kinds), p=w / w.sum()))]
    lo, hi = sorted((int(cfg["min_objects"]), int(cfg["max_objects"])))
    n = int(rng.integers(lo, hi + 1))
    desc = LAYOUTS[kind](catalog, rng, cfg, n)
    if not desc.objects:
        raise DropUnit("layout_empty", f"{kind}: no object could be placed")
    sim = build_model(desc, catalog.materials, cfg, int(cfg["views"]))
    t1 = time.perf_counter()
    info = settle(sim, cfg)
    t2 = time.perf_counter()
    boxes = scene_boxes(sim, desc)
    for k, (b, _) in enumerate(boxes):
        if b.top_z < -0.05 or np.any(np.abs(b.center[:2]) > desc.room_half + 2.5):
            raise DropUnit("object_escaped", f"{desc.objects[k].category.name} left the scene")
    focus = [s for s in desc.surfaces if s.id in desc.focus]
    on_focus = [b.center for b, _ in boxes]
    target = np.mean(on_focus, axis=0)  # aim at the objects, at the height of the main table top
    target[2] = focus[0].z
    from refspatial_gen.core.geometry import Box3D

    blockers = [b for b, _ in boxes] + [Box3D(sb.center, 2 * sb.half, np.eye(3)) for sb in desc.statics]
    cams = sample_cameras(kind, target, focus[0].z, blockers, rng, cfg, int(cfg["views"]), desc.room_half,
                          np.array([b.center for b, _ in boxes]))
    if not cams:
        raise DropUnit("no_camera_pose", "every sampled camera was inside an object")
    renders = render_views(sim, cams)
    t3 = time.perf_counter()
    meta = {"layout": kind, "settle_steps": int(info["steps"]), "n_objects": len(desc.objects)}
    frames = make_frames(unit_key, desc, sim, cams, renders, boxes, meta)
    frames = [f for f in frames if len(f.objects) >= int(cfg["min_visible_objects"])]
    t4 = time.perf_counter()
    if not frames:
        raise DropUnit("too_few_visible_objects", f"fewer than {cfg['min_visible_objects']} objects visible in every view")
    for f in frames:
        f.validate()
    for k, v in (("layout", t1 - t0), ("physics", t2 - t1), ("render", t3 - t2), ("frames", t4 - t3)):
        t[k] = t.get(k, 0.0) + v
    if keep_scene:
        return frames, desc, sim
    return frames


class SimSource:
    """Simulated tabletop and room scenes (MuJoCo). Unit keys are "sim:000017"."""

    name = "sim"
    CONFIG_FIELDS = CONFIG_FIELDS

    def unit_keys(self, config: dict[str, Any], scenes: int | None, input_path: str | None) -> list[str]:
        n = scenes if scenes is not None else int(_cfg(config)["scenes"])
        return [f"sim:{i:06d}" for i in range(n)]

    def load(self, unit_key: str, rng: np.random.Generator, config: dict[str, Any]) -> list[Frame]:
        return generate(unit_key, rng, config)
