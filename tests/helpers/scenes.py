"""Toy scenes with their scene graphs, for QA tests that need a few reproducible frames."""

from __future__ import annotations

import numpy as np

from refspatial_gen.core.model import Frame, SceneGraph
from refspatial_gen.graph import build_graph
from refspatial_gen.sources.toy import toy_frame


def toy_scenes(seeds, n_objects: int) -> list[tuple[Frame, SceneGraph]]:
    """(frame, graph) for each seed: a toy table scene with `n_objects` objects, frame id toy:<seed>."""
    out = []
    for seed in seeds:
        f = toy_frame(np.random.default_rng(seed), n_objects, frame_id=f"toy:{seed:06d}")
        out.append((f, build_graph(f)))
    return out
