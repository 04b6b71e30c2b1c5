"""CLI: `refspatial-gen sim usd|gallery|bench|describe` (asset commands are in cli/assets.py)."""

from __future__ import annotations

import argparse
import json
import sys

import numpy as np


def _config(args) -> dict:
    cfg: dict = {}
    if getattr(args, "recipe", None):
        from refspatial_gen.recipe import load_recipe

        spec = next((s for s in load_recipe(args.recipe).sources if s.kind == "sim"), None)
        if spec is None:
            raise SystemExit(f"{args.recipe}: no sim source")
        cfg = {k: v for k, v in spec.config.items() if not k.startswith("_")}
    if getattr(args, "catalog", None):
        cfg["catalog"] = args.catalog
    if getattr(args, "layout", None):
        cfg["layouts"] = {args.layout: 1.0}
    if getattr(args, "external_prob", None) is not None:
        cfg["external_prob"] = args.external_prob
    if getattr(args, "views", None):
        cfg["views"] = args.views
    return cfg


def _unit_rng(seed: int, unit: str) -> np.random.Generator:
    """The generator a run would give this unit (run/ derives it from seed and unit key) when available."""
    try:
        from refspatial_gen.run.plan import unit_rng  # the run's own derivation, so exports match shards
    except ImportError:
        unit_rng = None
    if unit_rng is not None:
        return unit_rng(seed, unit)
    import hashlib

    h = int.from_bytes(hashlib.sha256(f"{seed}:{unit}".encode()).digest()[:8], "little")
    return np.random.default_rng(h)


def cmd_usd(args) -> int:
    from refspatial_gen.sources.sim import generate
    from refspatial_gen.sources.sim.usd import export_usd
    from refspatial_gen.assets import load_catalog

    cfg = _config(args)
    frames, desc, sim = generate(args.unit, _unit_rng(args.seed, args.unit), cfg, keep_scene=True)
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

    cfg = _config(args)
    frames, desc, sim = generate(args.unit, _unit_rng(args.seed, args.unit), cfg, keep_scene=True)
    cat = load_catalog(catalog_paths(cfg.get("catalog")) or None)
    scene = SettledScene(desc, sim, cat.colors, cat.materials).describe([f.camera for f in frames])
    out = scene.save(args.out)
    print(f"wrote {out}/scene.json ({len(scene.meshes)} meshes, {len(scene.lights)} lights, {len(scene.cameras)} cameras)")
    return 0


def cmd_gallery(args) -> int:
    from refspatial_gen.sources.sim.gallery import gallery

    info = gallery(args.out, args.scenes, args.seed, _config(args), thumb_width=args.thumb_width, quality=args.quality)
    print(json.dumps(info, sort_keys=True))
    return 0


def cmd_bench(args) -> int:
    from refspatial_gen.sources.sim.bench import stage_times

    print(json.dumps(stage_times(args.scenes, args.seed, _config(args)), indent=1, sort_keys=True))
    return 0


def register(sub: argparse._SubParsersAction) -> None:
    s = sub.add_parser("sim", help="simulated scenes: USD export, preview gallery, timing")
    ssub = s.add_subparsers(dest="sim_command", required=True)

    def common(p):
        p.add_argument("--seed", type=int, default=0)
        p.add_argument("--catalog", default="")
        p.add_argument("--layout", choices=["tabletop", "room"], default=None)
        p.add_argument("--recipe", default="", help="take the sim source's config from this recipe")
        p.add_argument("--external-prob", type=float, default=None, dest="external_prob")
        p.add_argument("--views", type=int, default=None)

    u = ssub.add_parser("usd", help="export one generated scene to USD (.usda / .usdc)")
    u.add_argument("--unit", default="sim:000000")
    u.add_argument("--out", required=True)
    common(u)
    u.set_defaults(func=cmd_usd)
    d = ssub.add_parser("describe", help="write one scene's renderer-neutral description (scene.json, meshes.npz, textures)")
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


if __name__ == "__main__":
    sys.exit(0)
