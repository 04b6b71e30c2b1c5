"""Values placed at relation margins: every QA pair the pipeline emits must verify on the stored shard.

Why: the generator decides relations on its own numbers and `verify` re-decides them on the frame a shard
stores. Both compare with the same strict rules (`v > margin`), so they can only disagree where their
numbers differ: a frame rounded by serialisation, node attributes rounded for storage. These scenes put
heights, centre heights and camera-x offsets within a few micrometres of the margins (and thin objects
side by side at one level), write the unit's sample through the real shard writer, read it back, verify.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from refspatial_gen.core.camera import Camera, look_at
from refspatial_gen.core.errors import DropUnit
from refspatial_gen.core.geometry import Box3D, rot_z
from refspatial_gen.graph.constants import thresholds_for
from refspatial_gen.qa.verify import verify_sample
from refspatial_gen.recipe import load_recipe
from refspatial_gen.run import pipeline
from refspatial_gen.run.plan import Unit
from refspatial_gen.shards import ShardWriter, read_samples
from refspatial_gen.sources.toy import TABLE, toy_frame

REPO = Path(__file__).resolve().parents[1]
TH = thresholds_for("tabletop", "toy", None)
EPS = st.floats(-3e-6, 3e-6, allow_nan=False)  # well inside the rounding of stored boxes (1e-6)
ODD = st.floats(0.0, 1.0, allow_nan=False)  # offsets with many decimals, so storage rounding moves them


def margin_frame(jitter: float, objs: list[tuple[int, float, float, float]]) -> object:
    """Objects in a diagonal row seen from the front: consecutive centres `lateral_margin + e` apart along
    the camera's x axis (and 9 cm apart in depth); heights on a grid of `height_margin_abs` plus a tiny
    offset, or thin (below the stack tolerance) so they lie side by side at the table's level."""
    top = TABLE.top_z
    W, H = 160, 120
    eye = np.array([0.05 + 0.1 * jitter, -0.95, top + 0.62])
    pose = look_at(eye, np.array([0.0, 0.05, top]))
    f = W / (2 * np.tan(np.deg2rad(60) / 2))
    cam = Camera(W, H, f, f, W / 2, H / 2, pose)
    xcam = pose[:3, 0]
    fwd = np.array([pose[0, 2], pose[1, 2], 0.0])
    fwd /= np.linalg.norm(fwd)
    boxes = []
    p = np.array([-0.18 + 0.01 * jitter, -0.15, 0.0])
    for k, (steps, e_lat, e_h, odd) in enumerate(objs):
        if k:
            p = p + (TH.lateral_margin + e_lat) * xcam + 0.09 * fwd
        h = TH.stack_tolerance * 0.8 + e_h if steps < 0 else 0.03 + steps * TH.height_margin_abs + e_h
        size = np.array([0.04 + 0.001 * odd, 0.03, h])
        c = np.array([p[0] + 1e-4 * odd, p[1], top + h / 2])
        boxes.append(("box" if steps >= 0 else "book", "red" if k % 2 else "blue", Box3D(c, size, rot_z(0.3 * odd))))
    return toy_frame(np.random.default_rng(0), boxes=boxes, camera=cam, width=W, height=H, frame_id="toy:margin")


class _Source:
    def __init__(self, frame: object) -> None:
        self.frame = frame

    def load(self, unit_key: str, rng: np.random.Generator, config: dict) -> list:
        return [self.frame]


@pytest.fixture(scope="module")
def recipe():
    return load_recipe(REPO / "recipes" / "default.yaml")


OBJECT = st.tuples(st.integers(-1, 4), EPS, EPS, ODD)


@settings(max_examples=25, deadline=None, suppress_health_check=[HealthCheck.function_scoped_fixture])
@given(jitter=ODD, objs=st.lists(OBJECT, min_size=3, max_size=6), seed=st.integers(0, 2**16))
def test_pairs_at_margins_verify_on_the_stored_shard(recipe, tmp_path, monkeypatch, jitter, objs, seed):
    frame = margin_frame(jitter, objs)
    monkeypatch.setattr(pipeline, "get_source", lambda kind: _Source(frame))
    unit = Unit(f"s0/toy:{seed}", recipe.sources[0].index, "toy", f"toy:{seed}")
    try:
        sample = pipeline.make_sample(recipe, unit, pipeline.StageTimer())
    except DropUnit:
        return
    path = tmp_path / f"m{seed}.mcap"
    w = ShardWriter(path)
    w.write(sample)
    w.finish()
    stored = list(read_samples(path))
    assert len(stored) == 1 and len(stored[0].qa) == len(sample.qa)
    fails = verify_sample(stored[0])
    assert fails == [], fails[:3]


def test_stored_graph_decides_as_the_geometry():
    """Sizes, between and sectors are decided on stored node attributes: rounded copies (heights to 1e-5)
    put a 9.996 mm height difference at the 10 mm margin, so the graph said "taller" where the geometry
    (and so `verify`) says undecided. Every cell of a binary relation must equal its evaluation."""
    from refspatial_gen.graph import build_graph, geometry
    from refspatial_gen.graph.relations import evaluate
    from refspatial_gen.graph.tables import RelationTables

    top = TABLE.top_z
    heights = [0.05, 0.040004, 0.030001, 0.0600049]
    centres = [np.array([-0.2 + 0.13 * k, 0.03 * (k % 2), top + h / 2]) for k, h in enumerate(heights)]
    boxes = [("box", "red", Box3D(c, np.array([0.05, 0.05, h]), np.eye(3))) for c, h in zip(centres, heights)]
    frame = toy_frame(np.random.default_rng(0), boxes=boxes, frame_id="toy:heights")
    graph = build_graph(frame)
    tables, geom = RelationTables(graph), geometry(frame, {"scale": graph.meta["scale"]})
    ids = [o.id for o in frame.objects]
    checked = 0
    for rid in ("tall", "short", "big", "small", "wide", "thin"):
        for a in ids:
            for b in ids:
                if a != b and (c := tables.cell(rid, (a, b))) is not None:
                    assert c.holds == evaluate(geom, rid, a, b).holds, (rid, a, b, c)
                    checked += 1
    assert checked == 6 * len(ids) * (len(ids) - 1)
