"""`make bench REWRITE=1`: rewrites per second and the share accepted, against the local llama.cpp server
(SmolLM2-135M-Instruct on CPU), on a few default-recipe scenes, with an empty reply cache."""

from __future__ import annotations

import time
from pathlib import Path
from typing import Any


def bench_rewrite(work: Path, scenes: int = 2, recipe: Path | None = None) -> dict[str, Any]:
    from refspatial_gen.recipe import load_recipe
    from refspatial_gen.rewrite import llama_local
    from refspatial_gen.rewrite.config import load_rewrite_file
    from refspatial_gen.rewrite.dataset import accepted_share, rewrite_dir
    from refspatial_gen.run.executor import RecipeRef, run_plan

    why = llama_local.missing()
    if why:
        return {"skipped": why}
    root = Path(__file__).resolve().parents[2]
    recipe = recipe or root / "recipes" / "default.yaml"
    src = work / "rewrite-src"
    run_plan(
        load_recipe(recipe, scenes=scenes), RecipeRef(str(recipe), None, scenes, None), src, workers=1, progress=False
    )
    cfg = load_rewrite_file(root / "recipes" / "rewrite" / "local.yaml")
    with llama_local.llama_server(work / "llama.log") as url:
        from dataclasses import replace

        cfg = replace(cfg, server=url)
        t = time.perf_counter()
        res = rewrite_dir(src, work / "rewrite-out", cfg, cache_dir=work / "rewrite-cache")
        dt = time.perf_counter() - t
    c = res["counts"]
    n = sum(c.values())
    return {
        "model": cfg.model,
        "pairs_sent": n,
        "seconds": round(dt, 1),
        "rewrites_per_s": round(n / dt, 3) if dt > 0 else 0.0,
        "accepted_share": round(accepted_share(c), 3),
        "outcomes": c,
    }
