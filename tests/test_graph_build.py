"""Graph building as a whole: the relations CLI, stored size, determinism, JSON round trip, speed, and
that every one of the 31 relations has decided instances on typical tabletop scenes."""

from __future__ import annotations

import json
from collections import Counter

import numpy as np

from refspatial_gen.cli import main
from refspatial_gen.core.model import SceneGraph
from refspatial_gen.core.serialize import dumps
from refspatial_gen.graph import build_graph
from refspatial_gen.graph.query import GraphIndex
from refspatial_gen.graph.relations import REGISTRY, SPEC_31
from refspatial_gen.sources.toy import toy_frame


def test_relations_cli_json_lists_the_31(capsys):
    assert main(["relations", "--json"]) == 0
    d = json.loads(capsys.readouterr().out)
    rows = {r["id"]: r for r in d["relations"]}
    assert d["count"] == len(rows) >= 31
    for rid in SPEC_31:
        r = rows[rid]
        assert (
            r["in_31"]
            and r["name"]
            and r["frame"] in ("cam", "img", "world", "obj")
            and r["sources"]
            and r["definition"]
        )
    assert {"on", "under", "next_to", "obj_left"} <= set(rows)
    assert main(["relations"]) == 0
    assert "far_from" in capsys.readouterr().out


def test_graph_is_deterministic_compact_and_round_trips():
    f = toy_frame(np.random.default_rng(5), 15, 640, 480, frame_id="toy:5")
    g1, g2 = build_graph(f), build_graph(f)
    b1 = dumps(g1.to_json())
    assert b1 == dumps(g2.to_json())
    assert len(f.objects) >= 12
    assert len(b1) < 100_000, f"graph JSON is {len(b1)} bytes"
    back = SceneGraph.from_json(json.loads(b1))
    assert dumps(back.to_json()) == b1
    # the index answers identically from the round-tripped graph
    i1, i2 = GraphIndex(g1, f), GraphIndex(back, f)
    for rel in ("left", "between", "tall", "close", "facing", "obj_left", "inside", "corner"):
        a = [(x.args, x.holds) for x in i1.instances(rel, decided_only=False)]
        b = [(x.args, x.holds) for x in i2.instances(rel, decided_only=False)]
        assert a == b and a


def _spread_boxes(rng, n):
    from refspatial_gen.core.geometry import Box3D, rot_z
    from refspatial_gen.sources.toy import CATEGORIES, COLOURS, TABLE

    # a can standing in an open container (a box), so "inside" has instances too
    x, y = rng.uniform(-0.3, 0.3), rng.uniform(-0.15, 0.15)
    out = [
        ("box", "white", Box3D(np.array([x, y, TABLE.top_z + 0.04]), np.array([0.18, 0.18, 0.08]), np.eye(3))),
        ("can", "red", Box3D(np.array([x, y, TABLE.top_z + 0.08]), np.array([0.06, 0.06, 0.16]), np.eye(3))),
    ]
    # a block resting on a tray, so above/below (world) hold too (objects side by side on the table are
    # neither above nor below one another)
    x2, y2 = x + (0.33 if x < 0 else -0.33), 0.0
    out += [
        ("tray", "green", Box3D(np.array([x2, y2, TABLE.top_z + 0.0125]), np.array([0.25, 0.17, 0.025]), np.eye(3))),
        ("block", "yellow", Box3D(np.array([x2, y2, TABLE.top_z + 0.05]), np.array([0.05, 0.05, 0.05]), np.eye(3))),
    ]
    while len(out) < n:
        cat = str(rng.choice(sorted(CATEGORIES)))
        size = np.array([rng.uniform(*r) for r in CATEGORIES[cat]])
        c = np.array([rng.uniform(-0.52, 0.52), rng.uniform(-0.32, 0.32), TABLE.top_z + size[2] / 2])
        b = Box3D(c, size, rot_z(rng.uniform(-np.pi, np.pi)))
        if all(
            np.linalg.norm(b.center[:2] - o.center[:2])
            > (np.linalg.norm(b.size[:2]) + np.linalg.norm(o.size[:2])) / 2 + 0.005
            for _, _, o in out
        ):
            out.append((cat, str(rng.choice(sorted(COLOURS))), b))
    return out


def test_every_relation_is_decidable_on_typical_tabletop_scenes():
    """Across 8 random tabletop scenes (objects anywhere on the table, corners included) every one of the 31
    relations has decided instances that hold (and, for comparisons, instances that do not), so the QA engine
    can ask about each."""
    true, false = Counter(), Counter()
    for seed in range(8):
        f = toy_frame(np.random.default_rng(1000 + seed), boxes=_spread_boxes(np.random.default_rng(seed), 9))
        idx = GraphIndex(build_graph(f), f)
        for rel in SPEC_31:
            for inst in idx.instances(rel):
                true[rel] += inst.holds is True
                false[rel] += inst.holds is False
    for rel in SPEC_31:
        # the toy camera leaves most near table corners outside the picture: those are not named since audit
        # round 4 (graph/surface_seen.py, corner_unseen), so corners hold less often than the other relations
        need = 2 if rel == "corner" else 3
        assert true[rel] >= need, f"{rel}: only {true[rel]} holding instances"
        if REGISTRY[rel].storage not in ("unary", "region") and rel not in ("distance", "angle"):
            assert false[rel] >= 3, f"{rel}: only {false[rel]} failing instances"


def test_bad_config_and_frames():
    import pytest

    from refspatial_gen.core.errors import DropUnit

    f = toy_frame(np.random.default_rng(1), 4, 160, 120)
    with pytest.raises(ValueError, match="unknown graph config"):
        build_graph(f, {"nonsense": 1})
    with pytest.raises(ValueError, match="unknown threshold"):
        build_graph(f, {"thresholds": {"nonsense": 1.0}})
    f.depth[:] = np.nan
    with pytest.raises(DropUnit):
        build_graph(f)
