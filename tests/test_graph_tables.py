"""Whole-relation tables (graph/tables.py) answer exactly what single-cell lookups answer: each relation's
table rule and cell rule are separate code, so every cell of every table is compared."""

from __future__ import annotations

from itertools import permutations

import pytest

from refspatial_gen.core.model import RelationFact, SceneGraph
from refspatial_gen.graph.relations import REGISTRY
from refspatial_gen.graph.relations.base import HOLDS_OF_CODE, T_MISSING
from refspatial_gen.graph.tables import RelationTables
from tests.helpers.scenes import toy_scenes


@pytest.fixture(scope="module")
def graphs() -> list[SceneGraph]:
    out = [g for _f, g in toy_scenes(range(100, 104), 7)]
    # toy scenes have no containment or contact: plant stored inside / touching instances (true, undecided,
    # touching stored in the reverse direction) so those tables are exercised too
    g2 = SceneGraph.from_json(out[0].to_json())
    a, b, c, d, e = sorted(n.object_id for n in g2.nodes)[:5]
    g2.facts += [
        RelationFact("inside", (a, b), True, 0.9, 0.1),
        RelationFact("inside", (c, d), None, 0.3, 0.1),
        RelationFact("touching", (b, a), True, 0.0, 0.01),
        RelationFact("touching", (d, e), None, 0.01, 0.01),
    ]
    return [*out, g2]


def test_binary_tables_equal_their_cells(graphs: list[SceneGraph]) -> None:
    seen: dict[str, set[object]] = {}
    for g in graphs:
        t, ref = RelationTables(g), RelationTables(g)  # ref: cells only
        for rel in REGISTRY.values():
            rows = t.codes(rel.id)
            if rows is None:
                continue
            cols = t.columns(rel.id)
            assert cols is not None
            for (i, a), (j, b) in permutations(enumerate(t.ids), 2):
                want = ref.cell(rel.id, (a, b))
                code = rows[i][j]
                assert cols[j][i] == code
                if want is None:
                    assert code == T_MISSING, (rel.id, a, b)
                else:
                    assert code != T_MISSING and HOLDS_OF_CODE[code] is want.holds, (rel.id, a, b, code, want)
                seen.setdefault(rel.id, set()).add(code)
    # every table kind was reached, with true, false and undecided codes among them
    assert {"left", "right", "above_world", "tall", "short", "inside", "outside", "touching", "facing"} <= set(seen)
    assert set().union(*seen.values()) >= {0, 1, 2}


def test_between_table_equals_its_cells(graphs: list[SceneGraph]) -> None:
    kinds: dict[object, int] = {}
    for g in graphs:
        t, ref = RelationTables(g), RelationTables(g)
        table = t.table("between")
        for a, b, c in permutations(t.ids, 3):
            want = ref.cell("between", (a, b, c))
            assert want is not None
            assert table.code(a, b, c) == (want.holds, want.value)
            yes, maybe = table.row(min(b, c), max(b, c))
            assert (True if a in yes else None if a in maybe else False) is want.holds
            kinds[want.holds] = kinds.get(want.holds, 0) + 1
        assert table.largest == max((len(r[0]) for r in table.rows.values()), default=0)
    assert kinds.get(True) and kinds.get(False)


def test_distance_matrix_matches_pairwise_lookup(graphs: list[SceneGraph]) -> None:
    """The one-pass stored-distance matrix equals the pair-by-pair lookup (either storage direction)."""
    for g in graphs:
        t = RelationTables(g)
        d = t.distance_array()
        for i, a in enumerate(t.ids):
            for j, b in enumerate(t.ids):
                want = 0.0 if a == b else t.distance(a, b)
                assert d[i, j] == (float("inf") if want is None else want)
