"""Per-image timing of the image source (decode, annotations, lifting), excluding the depth model.

`per_image_ms(input_path)` builds every frame of a collection once (after one warm-up frame, so imports
and the annotation index are not counted) and reports milliseconds per image. The lead's `make bench`
adds graph + QA time on the returned frames.
"""

from __future__ import annotations

import time
from typing import Any

import numpy as np

from refspatial_gen.core.errors import DropUnit


def per_image_ms(
    input_path: str, config: dict[str, Any] | None = None, limit: int | None = None, return_frames: bool = False
) -> dict[str, Any]:
    """Timing summary: {"images", "frames", "dropped", "ms_per_image" (mean, excl. depth), "median_ms",
    "p90_ms", "stages_ms" (mean per stage), "depth_ms_excluded"}; with return_frames, also "frames_list"."""
    from refspatial_gen.sources.image.annotations import load_collection
    from refspatial_gen.sources.image.source import _with_defaults, build_frame

    cfg = _with_defaults(config)
    coll = load_collection(input_path, cfg["format"], cfg["annotations"], cfg["images_dir"])
    ids = coll.ids()[:limit] if limit else coll.ids()
    if ids:  # warm-up: imports (open3d, cv2), estimator construction
        try:
            build_frame(coll, coll.images[ids[0]], np.random.default_rng(0), cfg)
        except DropUnit:
            pass
    per, stages, frames, dropped = [], {}, [], {}
    for iid in ids:
        tm: dict[str, float] = {}
        t0 = time.perf_counter()
        try:
            f = build_frame(coll, coll.images[iid], np.random.default_rng(0), cfg, timings=tm)
            frames.append(f)
        except DropUnit as e:
            dropped[e.reason] = dropped.get(e.reason, 0) + 1
        total = time.perf_counter() - t0
        per.append(1000.0 * (total - tm.get("depth", 0.0)))
        for k, v in tm.items():
            stages[k] = stages.get(k, 0.0) + 1000.0 * v
    n = max(len(ids), 1)
    out = {
        "images": len(ids),
        "frames": len(frames),
        "dropped": dict(sorted(dropped.items())),
        "ms_per_image": round(float(np.mean(per)), 2) if per else None,
        "median_ms": round(float(np.median(per)), 2) if per else None,
        "p90_ms": round(float(np.percentile(per, 90)), 2) if per else None,
        "stages_ms": {k: round(v / n, 2) for k, v in sorted(stages.items())},
        "depth_ms_excluded": round(stages.get("depth", 0.0) / n, 2),
    }
    if return_frames:
        out["frames_list"] = frames
    return out


if __name__ == "__main__":
    import json
    import sys

    print(
        json.dumps(per_image_ms(sys.argv[1] if len(sys.argv) > 1 else "../shared/data/coco_tiny_train2017"), indent=1)
    )
