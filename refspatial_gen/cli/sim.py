"""CLI: `refspatial-gen sim usd|gallery|bench|describe` (asset commands are in cli/assets.py)."""

from __future__ import annotations

import argparse
import json
from collections.abc import Callable
from pathlib import Path
from typing import Any

import numpy as np

DEFAULT_RECIPE = Path(__file__).resolve().parents[2] / "recipes" / "default.yaml"


def _config(args: argparse.Namespace, base: dict[str, Any] | None = None) -> dict[str, Any]:
    """The sim source's config: the recipe's (`base`) with the command line's overrides on top."""
    cfg: dict[str, Any] = dict(base or {})
    if getattr(args, "catalog", None):
        cfg["catalog"] = args.catalog
    if getattr(args, "layout", None):
        cfg["layouts"] = {args.layout: 1.0}
    if getattr(args, "external_prob", None) is not None:
        cfg["external_prob"] = args.external_prob
    if getattr(args, "views", None):
        cfg["views"] = args.views
    return cfg


def run_unit(args: argparse.Namespace) -> tuple[Callable[[str], np.random.Generator], dict[str, Any]]:
    """(unit key -> generator, source config) exactly as a run of `--recipe` makes them: the run seeds a unit
    from (recipe seed, "s<source index>/<unit key>") and passes the recipe's sim section, so `sim usd`,
    `describe` and `gallery` show the very scenes a run writes to its shards (unless an override changes the
    config)."""
    from refspatial_gen.recipe import load_recipe
    from refspatial_gen.run.plan import unit_rng

    recipe = load_recipe(args.recipe or DEFAULT_RECIPE)
    spec = next((s for s in recipe.sources if s.kind == "sim"), None)
    if spec is None:
        raise SystemExit(f"refspatial-gen sim: {args.recipe or DEFAULT_RECIPE}: no sim source")
    seed = recipe.seed if args.seed is None else args.seed
    base = {k: v for k, v in spec.config.items() if not k.startswith("_")}
    return (lambda key: unit_rng(seed, f"s{spec.index}/{key}")), _config(args, base)


def cmd_usd(args) -> int:
    from refspatial_gen.assets import load_catalog
    from refspatial_gen.sources.sim import generate
    from refspatial_gen.sources.sim.usd import export_usd

    rng_for, cfg = run_unit(args)
    frames, desc, sim = generate(args.unit, rng_for(args.unit), cfg, keep_scene=True)
    from refspatial_gen.sources.sim.source import catalog_paths

    out = export_usd(desc, sim, frames, args.out, load_catalog(catalog_paths(cfg.get("catalog")) or None).colors)
    print(f"wrote {out} ({len(desc.objects)} objects, {len(frames)} cameras)")
    return 0


def cmd_describe(args) -> int:
    """The renderer-neutral description of one settled scene (what a second renderer draws)."""
    from refspatial_gen.assets import load_catalog
    from refspatial_gen.sources.sim import generate
    from refspatial_gen.sources.sim.scene import SettledScene
    from refspatial_gen.sources.sim.source import catalog_paths

    rng_for, cfg = run_unit(args)
    frames, desc, sim = generate(args.unit, rng_for(args.unit), cfg, keep_scene=True)
    cat = load_catalog(catalog_paths(cfg.get("catalog")) or None)
    scene = SettledScene(desc, sim, cat.colors, cat.materials).describe([f.camera for f in frames])
    out = scene.save(args.out)
    print(
        f"wrote {out}/scene.json ({len(scene.meshes)} meshes, {len(scene.lights)} lights, {len(scene.cameras)} cameras)"
    )
    return 0


def cmd_gallery(args) -> int:
    from refspatial_gen.sources.sim.gallery import gallery

    rng_for, cfg = run_unit(args)
    info = gallery(args.out, args.scenes, 0, cfg, thumb_width=args.thumb_width, quality=args.quality, rng_for=rng_for)
    print(json.dumps(info, sort_keys=True))
    return 0


def cmd_bench(args) -> int:
    from refspatial_gen.sources.sim.bench import stage_times

    _, cfg = run_unit(args)
    print(json.dumps(stage_times(args.scenes, args.seed or 0, cfg), indent=1, sort_keys=True))
    return 0


def register(sub: argparse._SubParsersAction) -> None:
    s = sub.add_parser("sim", help="simulated scenes: USD export, preview gallery, timing")
    ssub = s.add_subparsers(dest="sim_command", required=True)

    def common(p):
        p.add_argument("--seed", type=int, default=None, help="run seed (default: the recipe's)")
        p.add_argument("--catalog", default="")
        p.add_argument("--layout", choices=["tabletop", "room"], default=None)
        p.add_argument(
            "--recipe",
            default="",
            help="the run whose scenes to show: its sim config, seed and unit seeding (default recipes/default.yaml)",
        )
        p.add_argument("--external-prob", type=float, default=None, dest="external_prob")
        p.add_argument("--views", type=int, default=None)

    u = ssub.add_parser("usd", help="export one generated scene to USD (.usda / .usdc)")
    u.add_argument("--unit", default="sim:000000")
    u.add_argument("--out", required=True)
    common(u)
    u.set_defaults(func=cmd_usd)
    d = ssub.add_parser(
        "describe", help="write one scene's renderer-neutral description (scene.json, meshes.npz, textures)"
    )
    d.add_argument("--unit", default="sim:000000")
    d.add_argument("--out", required=True, help="folder")
    common(d)
    d.set_defaults(func=cmd_describe)
    g = ssub.add_parser("gallery", help="contact sheet of generated scenes (PNG or JPEG)")
    g.add_argument("--out", required=True)
    g.add_argument("--scenes", type=int, default=24)
    g.add_argument("--thumb-width", type=int, default=320, dest="thumb_width")
    g.add_argument("--quality", type=int, default=85)
    common(g)
    g.set_defaults(func=cmd_gallery)
    b = ssub.add_parser("bench", help="seconds per stage and frames/s of the simulated source (one core)")
    b.add_argument("--scenes", type=int, default=10)
    common(b)
    b.set_defaults(func=cmd_bench)
