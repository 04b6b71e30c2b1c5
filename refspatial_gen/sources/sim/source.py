"""The simulated source: unit key -> random layout -> MuJoCo physics until at rest -> multi-view RGB-D frames."""

from __future__ import annotations

import time
from pathlib import Path
from typing import Any

import numpy as np

from refspatial_gen.core.errors import DropUnit, RecipeError, RecipeErrors
from refspatial_gen.core.model import Frame
from refspatial_gen.schema import Field
from refspatial_gen.yamlpos import line_of


def _weights_ok(v: Any) -> str | None:
    if not isinstance(v, dict) or not v:
        return "must map layout kinds to weights"
    from refspatial_gen.sources.sim.rooms import LAYOUTS

    for k, w in v.items():
        if k not in LAYOUTS:
            return f"unknown layout {k!r} (known: {', '.join(sorted(LAYOUTS))})"
        if not isinstance(w, (int, float)) or w < 0:
            return f"weight of {k!r} must be a number >= 0"
    if sum(v.values()) <= 0:
        return "weights must not all be 0"
    return None


def _range(lo: float, hi: float, what: str, integer: bool = False):
    def check(v: Any) -> str | None:
        num = (int,) if integer else (int, float)
        if not (
            isinstance(v, list)
            and len(v) == 2
            and all(isinstance(x, num) and not isinstance(x, bool) for x in v)
            and lo <= v[0] <= v[1] <= hi
        ):
            return f"must be [lo, hi] {what} with {lo} <= lo <= hi <= {hi}"
        return None

    return check


def _renderer_ok(v: Any) -> str | None:
    from refspatial_gen.sources.sim.renderers import renderer_names

    return None if v in renderer_names() else f"unknown renderer {v!r} (known: {', '.join(renderer_names())})"


def _themes_ok(v: Any) -> str | None:
    from refspatial_gen.sources.sim.rooms import THEMES

    bad = [t for t in v if t not in THEMES]
    return f"unknown room themes {bad} (known: {', '.join(sorted(THEMES))})" if bad else None


CONFIG_FIELDS: dict[str, Field] = {
    "scenes": Field(int, default=10, min=1, doc="number of scenes when the run does not say"),
    "layouts": Field(dict, default={"tabletop": 0.5, "room": 0.5}, check=_weights_ok, doc="layout kind -> weight"),
    "room_themes": Field(list, default=[], check=_themes_ok, doc="room themes to draw from (default: all)"),
    "objects_per_surface": Field(
        list,
        default=[3, 9],
        check=_range(0, 30, "objects", True),
        doc="objects on each focus surface (RefSpatial: 3-9 per tabletop)",
    ),
    "min_objects": Field(int, default=3, min=1, max=40, doc="movable objects on a tabletop, at least"),
    "max_objects": Field(int, default=24, min=1, max=40, doc="movable objects per scene, at most"),
    "width": Field(int, default=640, min=32, max=4096),
    "height": Field(int, default=480, min=32, max=4096),
    "views": Field(int, default=2, min=1, max=8, doc="cameras (frames) per scene"),
    "fovy_deg": Field(list, default=[45.0, 60.0], check=_range(1, 169, "degrees"), doc="vertical field of view range"),
    "pitch_deg": Field(list, default=[30.0, 60.0], check=_range(0, 89, "degrees"), doc="camera pitch below horizontal"),
    "camera_height": Field(
        list, default=[0.3, 0.8], check=_range(0.05, 5, "metres"), doc="tabletop eye above the table"
    ),
    "room_eye_height": Field(list, default=[1.2, 1.8], check=_range(0.3, 3, "metres"), doc="room eye above the floor"),
    "view_spread_deg": Field(float, default=70.0, min=0, max=180, doc="azimuth step between views"),
    "renderer": Field(str, default="mujoco", check=_renderer_ok, doc="renderer by name (see sources/sim/renderers.py)"),
    "blender": Field(dict, default={}, doc="Blender renderer settings (sources/sim/blender_render.py SETTINGS)"),
    "lights": Field(list, default=[1, 3], check=_range(1, 8, "lights", True), doc="number of lights"),
    "light_intensity": Field(
        list, default=[0.6, 1.4], check=_range(0.0, 10.0, "x"), doc="per-light intensity multiplier"
    ),
    "shadows": Field(bool, default=True, doc="the key light casts shadows"),
    "shadow_size": Field(int, default=2048, min=64, max=8192, doc="shadow map size"),
    "catalog": Field(
        (str, list), default="", doc="asset catalog YAML, or a list merged in order; relative to the recipe"
    ),
    "external_prob": Field(
        float,
        default=None,
        min=0,
        max=1,
        doc="chance that a tabletop object is an external mesh (default 0.5 if the catalog has any)",
    ),
    "repeat_prob": Field(
        float, default=0.35, min=0, max=1, doc="chance to repeat a category already in the scene (new colour)"
    ),
    "stack_prob": Field(float, default=0.2, min=0, max=1),
    "inside_prob": Field(float, default=0.3, min=0, max=1),
    "edge_prob": Field(float, default=0.3, min=0, max=1, doc="chance to place an object near an edge or corner"),
    "face_prob": Field(
        float, default=0.35, min=0, max=1, doc="chance that an object with a front faces another object"
    ),
    "settle_max_steps": Field(int, default=3000, min=100, doc="physics step cap; unsettled scenes are dropped"),
    "settle_lin_vel": Field(float, default=0.005, min=0, doc="m/s: at rest below this"),
    "settle_ang_vel": Field(float, default=0.05, min=0, doc="rad/s: at rest below this"),
    "timestep": Field(float, default=0.002, min=0.0005, max=0.01),
    "min_visible_objects": Field(int, default=2, min=0, doc="drop a view showing fewer objects"),
}


def defaults() -> dict[str, Any]:
    return {k: f.default for k, f in CONFIG_FIELDS.items()}


def _cfg(config: dict[str, Any]) -> dict[str, Any]:
    cfg = defaults()
    cfg.update({k: v for k, v in (config or {}).items() if v is not None})
    return cfg


def catalog_paths(value: Any, base: Path | None = None) -> list[str]:
    """The recipe's `catalog` value as absolute paths ([] = the built-in catalog)."""
    from refspatial_gen.assets.paths import resolve_path

    specs = [value] if isinstance(value, str) else list(value or [])
    return [p if p == "builtin" else str(resolve_path(p, base)) for p in specs if p]


def check_config(cfg: dict[str, Any], file: str, lines: dict, path: tuple, errors: list[RecipeError]) -> None:
    """Recipe-time checks that need the recipe's folder or the catalog: every path exists, the catalog
    parses, external meshes are there when asked for. Resolves `catalog` against the recipe's folder."""
    from refspatial_gen.assets import load_catalog
    from refspatial_gen.assets.catalog import DEFAULT_CATALOG

    where = line_of(lines, path + ("catalog",))
    raw = cfg.get("catalog")
    if isinstance(raw, list) and not all(isinstance(x, str) for x in raw):
        errors.append(RecipeError(file, where, "catalog must be a path or a list of paths"))
        return
    files = [str(DEFAULT_CATALOG) if p == "builtin" else p for p in catalog_paths(raw, Path(file).resolve().parent)]
    for f in files:
        if not Path(f).is_file():
            errors.append(
                RecipeError(
                    file,
                    where,
                    f"catalog {f} not found (paths are relative to the recipe's folder; "
                    "write one with `refspatial-gen assets import DIR --out FILE`)",
                )
            )
    if len(errors) or not files and raw:
        return
    cfg["catalog"] = files if len(files) != 1 else files[0]
    try:
        cat = load_catalog(files or None)
    except RecipeErrors as e:
        errors.extend(e.errors)
        return
    except RecipeError as e:
        errors.append(e)
        return
    ep = cfg.get("external_prob")
    if ep is not None and ep > 0 and not cat.external_names():
        errors.append(
            RecipeError(
                file,
                line_of(lines, path + ("external_prob",)),
                f"external_prob is {ep} but the catalog {cat.path} has no external meshes "
                "(import some with `refspatial-gen assets import DIR --out my_catalog.yaml`)",
            )
        )
    _check_blender(cfg, file, lines, path, errors)
    lo, hi = cfg.get("min_objects", 3), cfg.get("max_objects", 24)
    if lo > hi:
        errors.append(
            RecipeError(file, line_of(lines, path + ("min_objects",)), f"min_objects {lo} > max_objects {hi}")
        )


def _check_blender(cfg: dict[str, Any], file: str, lines: dict, path: tuple, errors: list[RecipeError]) -> None:
    """The `blender:` section's keys, and (for `renderer: blender`) that the Blender environment exists."""
    from refspatial_gen.schema import check_section
    from refspatial_gen.sources.sim.blender_render import SETTINGS, missing_reason, settings

    n = len(errors)
    check_section(cfg.get("blender"), SETTINGS, file, lines, path + ("blender",), errors)
    if cfg.get("renderer") == "blender" and len(errors) == n:
        why = missing_reason(settings(cfg))
        if why:
            errors.append(RecipeError(file, line_of(lines, path + ("renderer",)), f"renderer blender: {why}"))


def _focus_target(desc, boxes) -> tuple[np.ndarray, float]:
    """Where cameras aim: the middle of the objects on the focus surfaces, at their mean height."""
    focus = [s for s in desc.surfaces if s.id in desc.focus]
    on = [b.center for (b, _), o in zip(boxes, desc.objects) if _root_support(desc, o) in desc.focus]
    pts = on or [b.center for b, _ in boxes]
    target = np.mean(pts, axis=0)
    z = float(np.mean([s.z for s in focus])) if focus else float(target[2])
    target[2] = z
    return target, (float(max(s.z for s in focus)) if focus else z)


def _root_support(desc, o) -> str:
    keys = {p.key: p for p in desc.objects}
    seen = set()
    while ":" in o.support and o.support.split(":", 1)[1] in keys and o.key not in seen:
        seen.add(o.key)
        o = keys[o.support.split(":", 1)[1]]
    return o.support


def generate(
    unit_key: str,
    rng: np.random.Generator,
    config: dict[str, Any],
    timings: dict[str, float] | None = None,
    keep_scene: bool = False,
):
    """Frames for one scene (and, with keep_scene, the SceneDesc and settled SimModel for export)."""
    from refspatial_gen.assets import load_catalog
    from refspatial_gen.core.geometry import Box3D
    from refspatial_gen.sources.sim.cameras import sample_cameras
    from refspatial_gen.sources.sim.finish import draw_finishes
    from refspatial_gen.sources.sim.frames import make_frames, scene_boxes
    from refspatial_gen.sources.sim.lighting import sample_lights
    from refspatial_gen.sources.sim.physics import build_model, settle
    from refspatial_gen.sources.sim.renderers import get_renderer
    from refspatial_gen.sources.sim.rooms import LAYOUTS
    from refspatial_gen.sources.sim.scene import SettledScene

    cfg = _cfg(config)
    t = timings if timings is not None else {}
    t0 = time.perf_counter()
    catalog = load_catalog(catalog_paths(cfg["catalog"]) or None)
    cfg["_colors"] = catalog.colors
    if cfg.get("external_prob") is None:
        cfg["external_prob"] = 0.5 if catalog.external_names() else 0.0
    kinds = sorted(cfg["layouts"])
    w = np.array([float(cfg["layouts"][k]) for k in kinds])
    kind = kinds[int(rng.choice(len(kinds), p=w / w.sum()))]
    desc = LAYOUTS[kind](catalog, rng, cfg)
    if not desc.objects:
        raise DropUnit("layout_empty", f"{kind}: no object could be placed")
    desc.lights = sample_lights(rng, cfg, np.mean([o.pos for o in desc.objects], axis=0), desc.room_half)
    draw_finishes(desc.objects, catalog.material_ranges, rng)
    sim = build_model(desc, catalog.materials, cfg, int(cfg["views"]))
    t1 = time.perf_counter()
    info = settle(sim, cfg)
    t2 = time.perf_counter()
    boxes = scene_boxes(sim, desc)
    for k, (b, _) in enumerate(boxes):
        if b.top_z < -0.05 or np.any(np.abs(b.center[:2]) > desc.room_half + 0.3):
            raise DropUnit("object_escaped", f"{desc.objects[k].category.name} left the scene")
    target, support_z = _focus_target(desc, boxes)
    blockers = [b for b, _ in boxes] + [Box3D(sb.center, 2 * sb.half, np.eye(3)) for sb in desc.statics]
    cams = sample_cameras(
        kind,
        target,
        support_z,
        blockers,
        rng,
        cfg,
        int(cfg["views"]),
        desc.room_half,
        np.array([b.center for b, _ in boxes]),
    )
    if not cams:
        raise DropUnit("no_camera_pose", "every sampled camera was inside an object")
    renders = get_renderer(cfg["renderer"], cfg).render(
        SettledScene(desc, sim, catalog.colors, catalog.materials), cams
    )
    t3 = time.perf_counter()
    meta = {"layout": kind, "settle_steps": int(info["steps"]), "n_objects": len(desc.objects)}
    frames = make_frames(unit_key, desc, sim, cams, renders, boxes, meta)
    for f, r in zip(frames, renders):  # a renderer's per-view notes (Blender: its agreement with MuJoCo)
        f.meta.update(getattr(r, "meta", None) or {})
    frames = [f for f in frames if len(f.objects) >= int(cfg["min_visible_objects"])]
    t4 = time.perf_counter()
    if not frames:
        raise DropUnit(
            "too_few_visible_objects", f"fewer than {cfg['min_visible_objects']} objects visible in every view"
        )
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

    def check_config(self, cfg: dict[str, Any], file: str, lines: dict, path: tuple, errors: list[RecipeError]) -> None:
        check_config(cfg, file, lines, path, errors)

    def unit_keys(self, config: dict[str, Any], scenes: int | None, input_path: str | None) -> list[str]:
        n = scenes if scenes is not None else int(_cfg(config)["scenes"])
        return [f"sim:{i:06d}" for i in range(n)]

    def load(self, unit_key: str, rng: np.random.Generator, config: dict[str, Any]) -> list[Frame]:
        return generate(unit_key, rng, config)
