"""Timing of the simulated source per stage, for `make bench` (measured, never asserted)."""

from __future__ import annotations

import resource
import time
from typing import Any

import numpy as np

from refspatial_gen.core.errors import DropUnit


def stage_times(n_scenes: int = 10, seed: int = 0, config: dict[str, Any] | None = None) -> dict[str, Any]:
    """Generate `n_scenes` scenes in this process; seconds per stage (summed), frames/s and drops.

    Stages: layout (catalog, meshes, placement, MjSpec compile), physics (settling), render (all views:
    RGB + depth + segmentation), frames (masks, boxes, fronts). One process = one core.
    """
    from refspatial_gen.sources.sim import generate

    t: dict[str, float] = {}
    frames, drops = 0, {}
    t0 = time.perf_counter()
    for i in range(n_scenes):
        key = f"sim:{i:06d}"
        rng = np.random.default_rng([seed, i])
        try:
            frames += len(generate(key, rng, config or {}, timings=t))
        except DropUnit as e:
            drops[e.reason] = drops.get(e.reason, 0) + 1
    total = time.perf_counter() - t0
    return {
        "scenes": n_scenes,
        "frames": frames,
        "dropped": dict(sorted(drops.items())),
        "seconds": {k: round(v, 3) for k, v in sorted(t.items())} | {"total": round(total, 3)},
        "frames_per_s": round(frames / total, 3) if total > 0 else 0.0,
        "ms_per_frame": {k: round(1000 * v / max(frames, 1), 1) for k, v in sorted(t.items())},
        "peak_rss_mb": round(resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024, 1),
    }
