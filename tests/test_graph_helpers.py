"""Hand-built box scenes for the scene-graph tests (no tests here; imported by test_graph_*.py).

The camera looks along +y from y = -1 m, 0.6 m above the table top (0.75 m), so camera x is world x
(left = -x), nearer = smaller y, and the table's far-left corner is (-0.6, +0.4).
"""

from __future__ import annotations

import numpy as np

from refspatial_gen.core.camera import Camera, look_at
from refspatial_gen.core.geometry import Box3D, rot_z
from refspatial_gen.graph import build_graph, geometry
from refspatial_gen.graph.query import GraphIndex
from refspatial_gen.graph.relations import evaluate
from refspatial_gen.sources.toy import TABLE, toy_frame

TOP = TABLE.top_z
W, H = 192, 144
F = W / (2 * np.tan(np.deg2rad(60) / 2))


def camera(eye=(0.0, -1.0, TOP + 0.6), target=(0.0, 0.0, TOP), w: int = W, h: int = H) -> Camera:
    f = w / (2 * np.tan(np.deg2rad(60) / 2))
    return Camera(w, h, f, f, w / 2, h / 2, look_at(np.array(eye, float), np.array(target, float)))


def box(x: float, y: float, size=(0.08, 0.08, 0.10), yaw: float = 0.0, z0: float = TOP) -> Box3D:
    """A box standing at (x, y) on a plane at height z0 (the table top by default)."""
    s = np.array(size, float)
    return Box3D(np.array([x, y, z0 + s[2] / 2]), s, rot_z(yaw))


def scene(*objects, cam: Camera | None = None, frame_id: str = "test"):
    """(frame, geometry) of boxes given as (category, colour, Box3D); object ids are 1, 2, ... in order."""
    frame = toy_frame(np.random.default_rng(0), boxes=list(objects), camera=cam or camera(), frame_id=frame_id)
    assert len(frame.objects) == len(objects), "every test object must be visible"
    return frame, geometry(frame)


def check(frame, geom, relation: str, args: tuple, expected):
    """Assert the relation's decision on the geometry AND through the stored graph's index."""
    f = evaluate(geom, relation, *args)
    assert f.holds is expected, (
        f"{relation}{args}: geometry says {f.holds} (value {f.value:.4f}, margin {f.margin:.4f})"
    )
    idx = GraphIndex(build_graph(frame, {"free_space": relation == "free_space"}), frame)
    g = idx.fact(relation, *args)
    assert g is not None and g.holds is expected, f"{relation}{args}: index says {None if g is None else g.holds}"
    return f
