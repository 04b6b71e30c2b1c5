"""`make bench`: throughput figures of every stage, measured on this machine (never asserted in tests).

Sections: the simulated pipeline end to end with a per-stage breakdown and peak memory; the same scenes
rendered by Blender Cycles (frames/s per core, agreement with MuJoCo's depth and masks); QA generation
from cached scene graphs; the image source per image; streaming reads vs. WebDataset; read throughput
of every export format on the same samples; and the run executor's scaling from 1 to 2 workers and its
memory when the number of scenes grows 10x. Opt-in (`--rewrite`, `make bench REWRITE=1`): LLM rewrites
per second and the share accepted against the local llama.cpp server (refspatial_gen/rewrite/bench.py);
(`--perception`, `make bench BENCH_ARGS=--perception`): unlabelled photos through full-size perception
models with random weights (perception/bench.py).
"""

from __future__ import annotations

import argparse
import json
import os
import platform
import shutil
import tempfile
import time
from pathlib import Path
from typing import Any

os.environ.setdefault("MUJOCO_GL", "egl")
os.environ.setdefault("PYOPENGL_PLATFORM", "egl")

ROOT = Path(__file__).resolve().parents[1]
DEFAULT_RECIPE = ROOT / "recipes" / "default.yaml"
SHARED = Path(os.environ.get("REFSPATIAL_SHARED_DATA", ROOT.parent / "shared" / "data"))


def _peak_mb() -> float:
    from refspatial_gen.run.executor import peak_rss_mb

    return peak_rss_mb()


def bench_sim(n_scenes: int, work: Path) -> dict[str, Any]:
    """The simulated pipeline in one process: layout, physics, render, graph, QA, write."""
    from refspatial_gen.graph import build_graph
    from refspatial_gen.qa import generate_qa
    from refspatial_gen.recipe import load_recipe
    from refspatial_gen.run.plan import unit_rng
    from refspatial_gen.shards.writer import ShardWriter
    from refspatial_gen.sources.sim import generate
    from refspatial_gen.core.errors import DropUnit
    from refspatial_gen.core.model import Sample

    recipe = load_recipe(DEFAULT_RECIPE)
    spec = next(s for s in recipe.sources if s.kind == "sim")
    t: dict[str, float] = {}
    frames_n = qa_n = dropped = 0
    writer = ShardWriter(work / "bench-sim.mcap", image_format=recipe.shards["image_format"])
    generate("sim:warmup", unit_rng(0, "warmup"), spec.config)  # renderer and catalog warm-up
    t_all = time.perf_counter()
    for i in range(n_scenes):
        key = f"sim:{i:06d}"
        rng = unit_rng(recipe.seed, key)
        try:
            frames = generate(key, rng, spec.config, timings=t)
        except DropUnit:
            dropped += 1
            continue
        t0 = time.perf_counter()
        graphs = [build_graph(f, recipe.graph) for f in frames]
        t1 = time.perf_counter()
        qa = generate_qa(frames, graphs, rng, recipe.qa)
        t2 = time.perf_counter()
        writer.write(Sample(key, frames, graphs, qa, key, {"source": "sim"}))
        t3 = time.perf_counter()
        for k, v in (("graph", t1 - t0), ("qa", t2 - t1), ("write", t3 - t2)):
            t[k] = t.get(k, 0.0) + v
        frames_n += len(frames)
        qa_n += len(qa)
    writer.finish()
    wall = time.perf_counter() - t_all
    return {"scenes": n_scenes, "dropped": dropped, "frames": frames_n, "qa_pairs": qa_n, "seconds": round(wall, 2),
            "frames_per_s": round(frames_n / wall, 2), "qa_per_s": round(qa_n / wall, 1),
            "ms_per_frame": {k: round(1000 * v / max(frames_n, 1), 1) for k, v in t.items()},
            "peak_rss_mb": round(_peak_mb(), 1), "size": "%dx%d" % (spec.config.get("width", 640), spec.config.get("height", 480))}


def bench_blender(n_scenes: int) -> dict[str, Any]:
    """The sim pipeline with `renderer: blender` (recipes/sim_blender.yaml: the default recipe's scenes, 640x480,
    16 samples + OpenImageDenoise) on one Cycles thread, so frames/s is per core; and how well Blender's own
    depth and object-index passes agree with MuJoCo's on these frames (mean and worst; no frame dropped here)."""
    import numpy as np

    from refspatial_gen.core.errors import DropUnit
    from refspatial_gen.recipe import load_recipe
    from refspatial_gen.run.plan import unit_rng
    from refspatial_gen.sources.sim import blender_render, generate

    recipe_path = ROOT / "recipes" / "sim_blender.yaml"
    cfg = next(s for s in load_recipe(DEFAULT_RECIPE).sources if s.kind == "sim").config
    blender = dict(next(s for s in load_recipe(recipe_path).sources if s.kind == "sim").config["blender"])
    why = blender_render.missing_reason(blender_render.settings({"blender": blender}))
    if why:
        return {"skipped": why}
    blender.update(threads=1, min_mask_iou=0.0, min_depth_agree=0.0)
    cfg = {**cfg, "renderer": "blender", "blender": blender}
    s = blender_render.settings(cfg)
    try:  # starts the Blender worker
        generate("sim:warmup", unit_rng(0, "warmup"), {**cfg, "width": 64, "height": 48})
    except DropUnit:
        pass
    blender_render.TIMES.clear()
    t: dict[str, float] = {}
    checks, dropped = [], {}
    t0 = time.perf_counter()
    for i in range(n_scenes):
        key = f"sim:{i:06d}"
        try:
            frames = generate(key, unit_rng(0, key), cfg, timings=t)
        except DropUnit as e:
            dropped[e.reason] = dropped.get(e.reason, 0) + 1
            continue
        checks += [f.meta["render_check"] for f in frames]
    wall = time.perf_counter() - t0
    n = len(checks)
    agree = {k: {"mean": round(float(np.mean([c[k] for c in checks])), 4), "worst": min(c[k] for c in checks)}
             for k in ("mask_iou_mean", "mask_iou_min", "depth_agree")} if checks else {}
    d = blender_render.settings({})
    below = sum(c["mask_iou_min"] < d["min_mask_iou"] or c["depth_agree"] < d["min_depth_agree"] for c in checks)
    return {"scenes": n_scenes, "frames": n, "dropped": dropped, "seconds": round(wall, 1),
            "frames_per_s_per_core": round(n / wall, 4) if wall else 0.0, "s_per_frame": round(wall / max(n, 1), 2),
            "ms_per_frame": {k: round(1000 * v / max(n, 1)) for k, v in t.items()},
            "blender_ms_per_frame": {k: round(1000 * v / max(n, 1)) for k, v in blender_render.TIMES.items()},
            "agreement_with_mujoco": agree, "frames_below_default_thresholds": below,
            "settings": {k: s[k] for k in ("device", "samples", "denoiser", "light_bounces", "threads")},
            "size": "%dx%d" % (cfg.get("width", 640), cfg.get("height", 480))}


def bench_qa(seconds: float) -> dict[str, Any]:
    from refspatial_gen.qa.bench import qa_throughput

    return qa_throughput(None, seconds)


def bench_image() -> dict[str, Any]:
    from refspatial_gen.sources.image.bench import per_image_ms

    folder = SHARED / "coco_tiny_train2017"
    if not folder.is_dir():
        return {"skipped": f"{folder} not found"}
    return per_image_ms(str(folder))


def bench_stream(shard_dir: Path, work: Path) -> dict[str, Any]:
    from refspatial_gen.shards.bench import stream_vs_webdataset

    return stream_vs_webdataset(shard_dir, work_dir=work / "wds")


def bench_scaling(scenes: int, mem_scenes: int, work: Path) -> dict[str, Any]:
    """Executor scaling 1 -> 2 workers, and per-worker peak memory for `scenes` vs 10x `scenes` (default recipe)."""
    from refspatial_gen.recipe import load_recipe
    from refspatial_gen.run.executor import RecipeRef, run_plan

    out: dict[str, Any] = {}
    ref = RecipeRef(str(DEFAULT_RECIPE), None, scenes, None)
    recipe = load_recipe(DEFAULT_RECIPE, scenes=scenes)
    walls = {}
    for w in (1, 2):
        d = work / f"scale-w{w}"
        res = run_plan(recipe, ref, d, workers=w, progress=False, fresh=True)
        walls[w] = res["run_log"]["wall_seconds"]
        out[f"workers_{w}"] = {"wall_s": walls[w], "qa_per_s": res["run_log"]["qa_per_s"],
                               "peak_rss_mb_per_worker": res["run_log"]["peak_rss_mb_per_worker"]}
        shutil.rmtree(d)
    out["speedup_1_to_2"] = round(walls[1] / walls[2], 2)
    mem = {}
    for n in (mem_scenes, mem_scenes * 10):
        d = work / f"mem-{n}"
        r = load_recipe(DEFAULT_RECIPE, scenes=n)
        res = run_plan(r, RecipeRef(str(DEFAULT_RECIPE), None, n, None), d, workers=2, progress=False, fresh=True)
        mem[n] = res["run_log"]["peak_rss_mb_per_worker"]
        shutil.rmtree(d)
    out["peak_rss_mb_per_worker_by_scenes"] = {str(k): v for k, v in mem.items()}
    out["memory_growth_10x"] = round(mem[mem_scenes * 10] / mem[mem_scenes], 3)
    return out


def bench_eval(scenes: int, work: Path) -> dict[str, Any]:
    """`refspatial-gen eval` on `scenes` default-recipe scenes: loading the ground truth (masks, free-space
    regions) and scoring gold predictions with every reward, in QA pairs per second."""
    from refspatial_gen.eval.baselines import predict
    from refspatial_gen.eval.dataset import load_items
    from refspatial_gen.eval.predictions import parse_predictions
    from refspatial_gen.eval.score import evaluate
    from refspatial_gen.recipe import load_recipe
    from refspatial_gen.run.executor import RecipeRef, run_plan

    d = work / "eval"
    run_plan(load_recipe(DEFAULT_RECIPE, scenes=scenes), RecipeRef(str(DEFAULT_RECIPE), None, scenes, None), d,
             workers=1, progress=False, fresh=True)
    t0 = time.perf_counter()
    items = load_items(d)
    t1 = time.perf_counter()
    preds = parse_predictions([json.dumps({"id": i, "text": t}) for i, t in predict("gold", items).items()], [it.id for it in items])
    recs = evaluate(items, preds)
    t2 = time.perf_counter()
    return {"qa_pairs": len(items), "load_gold_qa_per_s": round(len(items) / (t1 - t0), 1),
            "score_qa_per_s": round(len(items) / (t2 - t1), 1), "gold_success": sum(r["success"] for r in recs) / len(recs)}


def bench_perception(n: int, families: str) -> dict[str, Any]:
    """Opt-in (`--perception`, `--only perception`): photos through full-size random perception models."""
    from refspatial_gen.perception.bench import DEFAULT_FAMILIES, per_image

    folder = SHARED / "coco_tiny_train2017"
    if not folder.is_dir():
        return {"skipped": f"{folder} not found"}
    fams = tuple(families.split(",")) if families else DEFAULT_FAMILIES
    return per_image(folder, n, fams)


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(prog="python -m refspatial_gen.bench", description=__doc__)
    ap.add_argument("--scenes", type=int, default=24, help="scenes for the simulated pipeline")
    ap.add_argument("--scale-scenes", type=int, default=96, help="scenes for the 1 vs 2 worker scaling run")
    ap.add_argument("--mem-scenes", type=int, default=16, help="scenes for the memory run (and 10x as many)")
    ap.add_argument("--blender-scenes", type=int, default=4, dest="blender_scenes", help="scenes for the Blender renderer")
    ap.add_argument("--only", nargs="*", default=None,
                    choices=["sim", "blender", "qa", "image", "stream", "formats", "scale", "eval", "manifest", "rewrite",
                             "perception"])
    ap.add_argument("--rewrite", action="store_true", help="add the (slow) LLM rewrite section")
    ap.add_argument("--rewrite-scenes", type=int, default=2, help="default-recipe scenes whose pairs are rewritten")
    ap.add_argument("--perception", action="store_true",
                    help="add the (slow) perception section: full-size random models, minutes per photo on CPU")
    ap.add_argument("--perception-images", type=int, default=3)
    ap.add_argument("--perception-families", default="",
                    help="e.g. owlv2,sam2,depth-pro (default grounding-dino,sam,depth-anything)")
    ap.add_argument("--json", default=None, help="also write the figures to this file")
    args = ap.parse_args(argv)
    sections = args.only or (["sim", "blender", "qa", "image", "stream", "formats", "scale", "eval", "manifest"]
                             + (["rewrite"] if args.rewrite else []) + (["perception"] if args.perception else []))
    figures: dict[str, Any] = {"machine": f"{platform.machine()}, {os.cpu_count()} cores, {platform.python_version()}"}
    work = Path(tempfile.mkdtemp(prefix="refspatial-bench-"))
    try:
        for name in sections:
            t0 = time.perf_counter()
            if name == "sim":
                figures["sim"] = bench_sim(args.scenes, work)
            elif name == "blender":
                figures["blender"] = bench_blender(args.blender_scenes)
            elif name == "qa":
                figures["qa"] = bench_qa(5.0)
            elif name == "image":
                figures["image"] = bench_image()
            elif name == "stream":
                shard_dir = work / "stream"
                from refspatial_gen.shards.bench import make_toy_shards

                make_toy_shards(shard_dir)
                figures["stream"] = bench_stream(shard_dir, work)
            elif name == "formats":
                from refspatial_gen.shards.bench import format_throughput, make_toy_shards

                shard_dir = work / "formats"
                make_toy_shards(shard_dir)
                figures["formats"] = format_throughput(shard_dir, work_dir=work / "formats-out")
            elif name == "scale":
                figures["scale"] = bench_scaling(args.scale_scenes, args.mem_scenes, work)
            elif name == "eval":
                figures["eval"] = bench_eval(args.scenes, work)
            elif name == "manifest":  # input content hashing for the resume fingerprint (run/manifest.py)
                from refspatial_gen.run.manifest import bench_manifest

                figures["manifest"] = bench_manifest(work)
            elif name == "rewrite":
                from refspatial_gen.rewrite.bench import bench_rewrite

                figures["rewrite"] = bench_rewrite(work, args.rewrite_scenes)
            elif name == "perception":
                figures["perception"] = bench_perception(args.perception_images, args.perception_families)
            print(f"== {name} ({time.perf_counter() - t0:.1f} s)\n{json.dumps(figures[name], indent=2)}", flush=True)
    finally:
        shutil.rmtree(work, ignore_errors=True)
    if args.json:
        Path(args.json).write_text(json.dumps(figures, indent=2))
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
