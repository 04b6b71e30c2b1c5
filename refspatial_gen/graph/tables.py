"""RelationTables: a stored SceneGraph's relations as single-cell lookups and whole-relation tables.

Why: the QA engine must never recompute geometry, and asks thousands of "does R hold for these objects?"
questions per sample. Every relation declares (graph/relations/base.py) its storage, its rule for
instances a graph does not store (`cell`) and, where a whole table pays, how to build it (`table`); this
module applies those declarations with the rules every relation shares: unknown objects and world
relations without gravity are not evaluated, mirrors swap their first two arguments, negations flip the
decision, and tables are built once per graph on first use and kept.

Table codes: rows[i][j] is R(ids[i], ids[j]) over the sorted object ids: 1 true, 0 false, 2 undecided,
3 not evaluated (base.T_*).
"""

from __future__ import annotations

from typing import Any

import numpy as np

from refspatial_gen.core.model import FreeSpaceRegion, Node, RelationFact, SceneGraph
from refspatial_gen.graph.constants import Thresholds
from refspatial_gen.graph.relations import REGISTRY
from refspatial_gen.graph.relations.base import Cell, Relation, Rows

_RELATIONS = REGISTRY.loaded  # id -> Relation (every relation is registered as an object)
_FLIP = (1, 0, 2, 3)  # table code of not-R from R's
_UNSET = object()
_THRESHOLDS: dict[tuple[Any, ...], Thresholds] = {}


def thresholds_of(values: dict[str, Any]) -> Thresholds:
    """Thresholds from a graph's stored values; equal values share one (frozen) instance, since every graph
    of a run stores the same few sets and building one is a visible part of a table's set-up."""
    key = tuple(values.items())
    th = _THRESHOLDS.get(key)
    if th is None:
        th = Thresholds(**values)
        if len(_THRESHOLDS) > 64:
            _THRESHOLDS.clear()
        _THRESHOLDS[key] = th
    return th


def transpose(rows: Rows) -> Rows:
    return [list(col) for col in zip(*rows)]


class RelationTables:
    """Lookups over one stored SceneGraph (built lazily; nothing is computed before it is asked for)."""

    def __init__(self, graph: SceneGraph) -> None:
        self.graph = graph
        self.nodes: dict[int, Node] = {n.object_id: n for n in graph.nodes}
        self.ids: tuple[int, ...] = tuple(sorted(self.nodes))
        self.pos: dict[int, int] = {x: k for k, x in enumerate(self.ids)}  # id -> row of every table
        meta = graph.meta
        self.th: Thresholds | None = thresholds_of(meta["thresholds"]) if "thresholds" in meta else None
        self.world = bool(meta.get("world_relations", False))
        self.surfaces: dict[str, dict[str, Any]] = meta.get("surfaces", {})
        self._groups: dict[str, list[RelationFact]] | None = None
        self._stored: dict[str, dict[tuple[Any, ...], RelationFact]] = {}
        self._dist: np.ndarray[Any, np.dtype[np.float64]] | None = None
        self._dist_rows: list[list[float]] | None = None
        self._codes: dict[str, Rows | None] = {}
        self._tables: dict[str, Any] = {}
        self._shared: dict[str, Any] = {}

    # ------------------------------------------------------------------ stored facts
    def facts_of(self, relation: str) -> list[RelationFact]:
        """The stored facts of one relation, in storage order (all relations grouped in one pass, on first use)."""
        groups = self._groups
        if groups is None:
            groups = self._groups = {}
            for f in self.graph.facts:
                groups.setdefault(f.relation, []).append(f)
        return groups.get(relation, [])

    def stored(self, relation: str, args: tuple[Any, ...]) -> RelationFact | None:
        """The stored instance with exactly these arguments (a later duplicate wins), or None."""
        t = self._stored.get(relation)
        if t is None:
            t = self._stored[relation] = {tuple(f.args): f for f in self.facts_of(relation)}
        return t.get(tuple(args))

    def distance(self, a: Any, b: Any) -> float | None:
        """The stored surface distance of a pair (stored either way round), or None."""
        f = self.stored("distance", (a, b)) or self.stored("distance", (b, a))
        return None if f is None else float(f.value)

    def distance_array(self) -> np.ndarray[Any, np.dtype[np.float64]]:
        """Stored distances as a matrix over self.ids (inf where none is stored), from one pass over the facts:
        a pair stored either way round gives both entries, the (a, b) instance winning as distance() does."""
        if self._dist is None:
            n, pos = len(self.ids), self.pos
            d = np.full((n, n), np.inf)
            np.fill_diagonal(d, 0.0)
            direct = []
            for f in self.facts_of("distance"):
                args = f.args
                if len(args) == 2:
                    i, j = pos.get(args[0]), pos.get(args[1])
                    if i is not None and j is not None and i != j:
                        direct.append((i, j, float(f.value)))
            for i, j, v in direct:  # reversed instances first, so a stored (a, b) instance overrides them
                d[j, i] = v
            for i, j, v in direct:
                d[i, j] = v
            self._dist = d
        return self._dist

    def distance_rows(self) -> list[list[float]]:
        """distance_array() as Python lists (single reads without numpy scalars)."""
        if self._dist_rows is None:
            self._dist_rows = self.distance_array().tolist()
        return self._dist_rows

    def regions(self, kind: str | None = None, anchors: tuple[Any, ...] | None = None) -> list[FreeSpaceRegion]:
        return [
            r
            for r in self.graph.free_space
            if (kind is None or r.kind == kind) and (anchors is None or tuple(r.anchors) == tuple(anchors))
        ]

    def shared(self, key: str, build: Any) -> Any:
        """A computation several relations share (sizes compare all three quantities at once), kept."""
        v = self._shared.get(key, _UNSET)
        if v is _UNSET:
            v = self._shared[key] = build(self)
        return v

    # ------------------------------------------------------------------ single instances
    def cell(self, relation: str, args: tuple[Any, ...]) -> Cell | None:
        """The instance (decided or undecided), or None when it was not evaluated (unknown object, no gravity,
        no front direction, repeated argument...)."""
        rel = _RELATIONS.get(relation) or REGISTRY[relation]
        if len(args) != rel.arity and not rel.variadic:
            raise ValueError(f"{relation} takes {rel.arity} arguments, got {len(args)}")
        nodes = self.nodes
        for a in args:
            if isinstance(a, (int, np.integer)) and int(a) not in nodes:
                return None
        if rel.gated and not self.world:
            return None
        if rel.mirror_of:
            return self.cell(rel.mirror_of, (args[1], args[0], *args[2:]))
        if rel.negation_of:
            c = self.cell(rel.negation_of, args)
            return None if c is None else Cell(None if c.holds is None else not c.holds, c.value, c.margin)
        if len(set(args)) < len(args):
            return None
        if rel.cell is None:
            f = self.stored(relation, args)
            return None if f is None else Cell(f.holds, float(f.value), f.margin)
        return rel.cell(self, args)

    def fact(self, relation: str, *args: Any) -> RelationFact | None:
        c = self.cell(relation, tuple(args))
        return None if c is None else RelationFact(relation, tuple(args), c.holds, c.value, c.margin)

    # ------------------------------------------------------------------ whole tables
    def codes(self, relation: str) -> Rows | None:
        """rows[i][j] = code of relation(ids[i], ids[j]) for a binary relation with a table, else None."""
        if relation in self._codes:
            return self._codes[relation]
        rel = _RELATIONS.get(relation) or REGISTRY[relation]
        out: Rows | None = None
        if rel.gated and not self.world:
            out = None
        elif rel.mirror_of:
            base = self.codes(rel.mirror_of)
            out = None if base is None else transpose(base)
        elif rel.negation_of:
            base = self.codes(rel.negation_of)
            out = None if base is None else [[_FLIP[c] for c in row] for row in base]
        elif rel.table is not None and rel.arity == 2:
            out = rel.table(self)
        self._codes[relation] = out
        return out

    def columns(self, relation: str) -> Rows | None:
        """cols[j][i] = code of relation(ids[i], ids[j]): one list per anchor (the QA engine's sets)."""
        rel: Relation = _RELATIONS.get(relation) or REGISTRY[relation]
        if rel.mirror_of and not (rel.gated and not self.world):
            return self.codes(rel.mirror_of)  # mirror(x, anchor) = base(anchor, x): the base's rows
        rows = self.codes(relation)
        return None if rows is None else transpose(rows)

    def table(self, relation: str) -> Any:
        """The relation's own table object (e.g. between's BetweenTable), built once; None without one."""
        t = self._tables.get(relation, _UNSET)
        if t is _UNSET:
            rel = REGISTRY[relation]
            t = self._tables[relation] = (
                None if rel.table is None or (rel.gated and not self.world) else rel.table(self)
            )
        return t
