"""QA throughput from cached scene graphs, all checks on (`make bench`).

Why cached graphs: the number isolates the template engine (search, checks, rendering) from scene
generation and graph building; the per-sample lookup index is rebuilt for every sample so its cost is
included.
"""

from __future__ import annotations

import time
from pathlib import Path
from typing import Any

import numpy as np

from refspatial_gen.core.model import Frame, SceneGraph
from refspatial_gen.qa.config import QAConfig


def default_config() -> QAConfig:
    """The default recipe's qa section."""
    from refspatial_gen.qa.config import load_qa_config
    from refspatial_gen.yamlpos import load_yaml

    path = Path(__file__).resolve().parents[2] / "recipes" / "default.yaml"
    data, lines = load_yaml(path)
    return load_qa_config(data.get("qa") or {}, str(path), lines)


def toy_graphs(n: int = 8, seed: int = 0) -> list[tuple[Frame, SceneGraph]]:
    from refspatial_gen.graph import build_graph
    from refspatial_gen.sources.toy import toy_frame

    out = []
    for i in range(n):
        rng = np.random.default_rng(seed + i)
        f = toy_frame(rng, int(rng.integers(5, 9)), frame_id=f"toy:{i:06d}")
        out.append((f, build_graph(f)))
    return out


def qa_throughput(
    graphs_and_frames: list[tuple[Frame, SceneGraph]] | None = None,
    seconds: float = 3.0,
    config: QAConfig | None = None,
    fresh_index: bool = True,
) -> dict[str, Any]:
    """QA pairs per second on one core: generate_qa over cached (frame, graph) pairs for `seconds` of CPU
    time. `fresh_index` rebuilds the per-sample lookup index every time (the cost a run pays)."""
    from refspatial_gen.qa.generate import generate_qa, scene_index

    pairs = graphs_and_frames or toy_graphs()
    pairs = [(f, g) if isinstance(f, Frame) else (g, f) for f, g in pairs]
    cfg = config or default_config()
    n_qa = n_samples = 0
    t0 = time.process_time()
    w0 = time.perf_counter()
    k = 0
    while time.process_time() - t0 < seconds:
        f, g = pairs[k % len(pairs)]
        # fresh: generate_qa builds the sample's index itself (the cost a run pays); warm: a kept one is reused
        idx = None if fresh_index else [scene_index(f, g)]
        n_qa += len(generate_qa([f], [g], np.random.default_rng(k), cfg, indexes=idx))
        n_samples += 1
        k += 1
    cpu = time.process_time() - t0
    return {
        "qa_pairs": n_qa,
        "samples": n_samples,
        "cpu_seconds": round(cpu, 3),
        "wall_seconds": round(time.perf_counter() - w0, 3),
        "qa_per_second_per_core": round(n_qa / cpu, 1) if cpu > 0 else 0.0,
        "qa_per_sample": round(n_qa / max(n_samples, 1), 2),
        "fresh_index": fresh_index,
        "target_qa_per_second_per_core": 5000,
    }


if __name__ == "__main__":
    import json

    pairs = toy_graphs()
    print(
        json.dumps(
            {"cold_index": qa_throughput(pairs), "warm_index": qa_throughput(pairs, fresh_index=False)}, indent=1
        )
    )
