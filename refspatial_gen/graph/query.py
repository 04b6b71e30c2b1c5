"""GraphIndex: answer "does relation R hold for these arguments?" from a stored SceneGraph.

Why: consumers of a stored graph (the QA engine, the stats, tests) must never recompute geometry. Every
rule lives with its relation (graph/relations/); graph/tables.py applies them. This class is the readable
front: nodes and phrases, single facts, free-space regions and every instance of a relation.
"""

from __future__ import annotations

from collections.abc import Iterator
from itertools import permutations
from typing import Any

import numpy as np

from refspatial_gen.core.model import Frame, FreeSpaceRegion, Node, RelationFact, SceneGraph
from refspatial_gen.graph.relations import REGISTRY
from refspatial_gen.graph.tables import RelationTables


class GraphIndex:
    """Index over one SceneGraph. `frame` is optional (only needed by callers that want pixels)."""

    def __init__(self, graph: SceneGraph, frame: Frame | None = None, tables: RelationTables | None = None) -> None:
        self.graph = graph
        self.frame = frame
        self.tables = tables if tables is not None else RelationTables(graph)
        self.nodes: dict[int, Node] = self.tables.nodes
        self.ids = list(self.tables.ids)
        self.th = self.tables.th
        self.world = self.tables.world
        self.surfaces = self.tables.surfaces

    # ------------------------------------------------------------------ nodes
    def node(self, object_id: int) -> Node:
        return self.nodes[int(object_id)]

    def phrase(self, object_id: int) -> str | None:
        p = self.nodes[int(object_id)].phrases
        return p[0] if p else None

    def referable(self) -> list[int]:
        """Ids of objects with at least one unique phrase and an answer point."""
        return [i for i in self.ids if self.nodes[i].phrases and self.nodes[i].point is not None]

    def center_distance(self, a: int, b: int) -> float:
        ca, cb = (np.array(self.nodes[int(x)].attributes["center"]) for x in (a, b))
        return float(np.linalg.norm(ca - cb))

    def regions(self, kind: str | None = None, anchors: tuple[Any, ...] | None = None) -> list[FreeSpaceRegion]:
        return self.tables.regions(kind, anchors)

    # ------------------------------------------------------------------ facts
    def holds(self, relation: str, *args: Any) -> bool | None:
        f = self.fact(relation, *args)
        return None if f is None else f.holds

    def fact(self, relation: str, *args: Any) -> RelationFact | None:
        """The relation instance (decided or undecided), or None when it was not evaluated (unknown
        object, no gravity, no front direction, ...)."""
        return self.tables.fact(relation, *args)

    def facts_of(self, relation: str) -> list[RelationFact]:
        """The stored facts of one relation, in storage order."""
        return self.tables.facts_of(relation)

    # ------------------------------------------------------------------ between, grouped
    def between_rows(self) -> dict[tuple[int, int], tuple[frozenset[int], frozenset[int]]]:
        """{(b, c) ids with b < c: (ids A with between(A, b, c) true, ids undecided)}; every other A is False."""
        t = self.tables.table("between")
        return {} if t is None else dict(t.rows)

    def between_row(self, b: int, c: int) -> tuple[frozenset[int], frozenset[int]]:
        t = self.tables.table("between")
        return (frozenset(), frozenset()) if t is None else t.row(b, c)

    def largest_between_row(self) -> int:
        t = self.tables.table("between")
        return 0 if t is None else int(t.largest)

    def between_code(self, a: int, b: int, c: int) -> tuple[bool | None, float]:
        """(holds, t) of between(a, b, c) for three distinct known ids, without building a RelationFact."""
        t = self.tables.table("between")
        return (False, 0.0) if t is None else t.code(a, b, c)

    # ------------------------------------------------------------------ enumeration
    def instances(self, relation: str, decided_only: bool = True) -> Iterator[RelationFact]:
        """Every evaluated instance of `relation` (mirrors and derived ones included), deterministic order."""
        rel = REGISTRY[relation]
        if rel.instances is not None:
            yield from rel.instances(self.tables)
            return
        if rel.domain is not None:
            arg_sets = rel.domain(self.tables)
        elif rel.arity == 1:
            arg_sets = [(i,) for i in self.ids]
        else:
            arg_sets = list(permutations(self.ids, rel.arity))
        for args in arg_sets:
            f = self.fact(relation, *args)
            if f is not None and (f.holds is not None or not decided_only):
                yield f
