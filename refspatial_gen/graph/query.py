"""GraphIndex: answer "does relation R hold for these arguments?" from a stored SceneGraph.

Why: the QA engine must never recompute geometry. Stored facts keep one canonical direction per pair
(mirrors and reversed pairs are derived here), sparse relations store only holding/undecided instances
(absent = False inside their domain), and a few relations are derived from stored node attributes and
distances with the very decision functions the builder uses (relations.sizes.compare, between_table,
orientation.bearings/sector_codes).
"""

from __future__ import annotations

from itertools import permutations
from typing import Iterator

import numpy as np

from refspatial_gen.core.model import FreeSpaceRegion, Node, RelationFact, SceneGraph
from refspatial_gen.graph.constants import Thresholds
from refspatial_gen.graph.relations import REGISTRY
from refspatial_gen.graph.relations.base import decide
from refspatial_gen.graph.relations.common import TRUE, holds_of
from refspatial_gen.graph.relations.containment import between_arrays
from refspatial_gen.graph.relations.orientation import SECTORS, angle_between, bearings, sector_codes
from refspatial_gen.graph.relations.sizes import DERIVED, compare

PAIR_REL = {"left", "front", "above_image", "above_world"}
SYMMETRIC_STORED = {"distance", "touching", "far_from", "next_to"}


_UNSET = object()  # not computed yet (between_arrays itself may return None)
_EMPTY_ROW: tuple[frozenset, frozenset] = (frozenset(), frozenset())

_THRESHOLDS: dict[tuple, Thresholds] = {}


def _thresholds(values: dict) -> Thresholds:
    """Thresholds from a graph's stored values; equal values share one (frozen) instance, since every graph
    of a run stores the same few sets and building one is most of an index's set-up."""
    key = tuple(values.items())
    th = _THRESHOLDS.get(key)
    if th is None:
        th = Thresholds(**values)
        if len(_THRESHOLDS) > 64:
            _THRESHOLDS.clear()
        _THRESHOLDS[key] = th
    return th


class _FactLookup:
    """(relation, args) -> the stored fact, like a dict over all facts (a later duplicate wins), but each
    relation's table is built on its first lookup: an index that only asks a few relations pays for those.
    Holds the graph, not the index (no reference cycle)."""

    __slots__ = ("_graph", "_groups", "_by")

    def __init__(self, graph: SceneGraph) -> None:
        self._graph, self._groups, self._by = graph, None, {}

    def facts_of(self, relation: str) -> list[RelationFact]:
        """The stored facts of one relation, in storage order (all relations grouped in one pass, on first use)."""
        groups = self._groups
        if groups is None:
            groups = self._groups = {}
            for f in self._graph.facts:
                groups.setdefault(f.relation, []).append(f)
        return groups.get(relation, [])

    def _table(self, relation: str) -> dict:
        t = self._by.get(relation)
        if t is None:
            t = self._by[relation] = {tuple(f.args): f for f in self.facts_of(relation)}
        return t

    def get(self, key: tuple, default=None):
        return self._table(key[0]).get(tuple(key[1]), default)

    def __contains__(self, key: tuple) -> bool:
        return tuple(key[1]) in self._table(key[0])

    def __getitem__(self, key: tuple) -> RelationFact:
        return self._table(key[0])[tuple(key[1])]


class GraphIndex:
    """Index over one SceneGraph. `frame` is optional (only needed by callers that want pixels)."""

    def __init__(self, graph: SceneGraph, frame=None) -> None:
        self.graph = graph
        self.frame = frame
        self.nodes: dict[int, Node] = {n.object_id: n for n in graph.nodes}
        self.ids = sorted(self.nodes)
        self._facts = _FactLookup(graph)  # (relation, args) -> stored fact
        self.th = _thresholds(graph.meta["thresholds"]) if "thresholds" in graph.meta else None
        self.world = bool(graph.meta.get("world_relations", False))
        self.surfaces: dict[str, dict] = graph.meta.get("surfaces", {})
        self._dist: np.ndarray | None = None
        self._pos: dict[int, int] = {x: k for k, x in enumerate(self.ids)}  # id -> row of the derived tables
        self._barr = _UNSET
        self._bpairs: dict | None = None
        self._bcells: tuple | None = None  # per anchor pair row: candidate mask, code, t (python lists)
        self._brow: dict[tuple[int, int], tuple[frozenset, frozenset]] = {}

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

    def regions(self, kind: str | None = None, anchors: tuple | None = None) -> list[FreeSpaceRegion]:
        return [r for r in self.graph.free_space
                if (kind is None or r.kind == kind) and (anchors is None or tuple(r.anchors) == tuple(anchors))]

    # ------------------------------------------------------------------ facts
    def holds(self, relation: str, *args) -> bool | None:
        f = self.fact(relation, *args)
        return None if f is None else f.holds

    def fact(self, relation: str, *args) -> RelationFact | None:
        """The relation instance (decided or undecided), or None when it was not evaluated (unknown
        object, no gravity, no front direction, ...)."""
        rel = REGISTRY[relation]
        args = tuple(args)
        if len(args) != rel.arity and relation not in ("free_space",):
            raise ValueError(f"{relation} takes {rel.arity} arguments, got {len(args)}")
        for a in args:
            if isinstance(a, (int, np.integer)) and int(a) not in self.nodes:
                return None
        if rel.needs and "gravity" in rel.needs and not self.world and relation != "rotation_vertical":
            return None
        if rel.mirror_of:
            swapped = (args[1], args[0], *args[2:])
            f = self.fact(rel.mirror_of, *swapped)
            return None if f is None else RelationFact(relation, args, f.holds, f.value, f.margin)
        if rel.negation_of:
            f = self.fact(rel.negation_of, *args)
            return None if f is None else RelationFact(relation, args, None if f.holds is None else not f.holds,
                                                       f.value, f.margin)
        if len(set(args)) < len(args):
            return None
        return self._lookup(relation, args)

    def _lookup(self, relation: str, args: tuple) -> RelationFact | None:
        key = (relation, args)
        if relation in PAIR_REL:
            if key in self._facts:
                return self._facts[key]
            f = self._facts.get((relation, args[::-1]))
            if f is None:
                return None
            return RelationFact(relation, args, None if f.holds is None else not f.holds, -f.value, f.margin)
        if relation in SYMMETRIC_STORED:
            f = self._facts.get(key) or self._facts.get((relation, args[::-1]))
            if f is not None:
                return RelationFact(relation, args, f.holds, f.value, f.margin)
            if relation == "distance":
                return None
            d = self._distance(*args)
            return None if d is None else RelationFact(relation, args, False, d, self._margin(relation))
        if relation in ("depth", "rotation_horizontal", "rotation_vertical"):
            return self._facts.get(key)
        if relation in ("on", "supported_by"):
            a, b = args
            s = self.nodes[int(a)].support
            target = b if isinstance(b, str) else f"obj:{int(b)}"
            f = self._facts.get(("on", args))
            if f is not None:
                return RelationFact(relation, args, f.holds, f.value, f.margin)
            return RelationFact(relation, args, False if s != target else None, 0.0, self.th.support_gap)
        if relation in ("under", "inside"):
            f = self._facts.get(key)
            if f is not None:
                return f
            return RelationFact(relation, args, False, 0.0, 0.15 if relation == "under" else self.th.inside_band)
        if relation in ("facing", "facing_away"):
            f = self._facts.get(key)
            if f is not None:
                return f
            if self.nodes[int(args[0])].attributes.get("front") is None:
                return RelationFact(relation, args, None, float(np.pi), self.th.facing_margin)
            return RelationFact(relation, args, False, float(np.pi), self.th.facing_margin)
        if relation in ("corner", "edge"):
            a, sid, label = args
            f = self._facts.get(key)
            if f is not None:
                return f
            labels = self.surfaces.get(sid, {}).get("corners" if relation == "corner" else "edges", [])
            if self.nodes[int(a)].attributes.get("surface") != sid or label not in labels:
                return None
            return RelationFact(relation, args, False, 0.0, self.th.surface_band_margin)
        if relation in DERIVED:
            attr, abs_name, rel_name = DERIVED[relation]
            q = np.array([self.nodes[int(x)].attributes[attr] for x in args], float)
            v, codes, m = compare(q, getattr(self.th, abs_name) if abs_name else 0.0, getattr(self.th, rel_name))
            return RelationFact(relation, args, holds_of(int(codes[0, 1])), float(v[0, 1]), float(m[0, 1]))
        if relation in ("close", "far"):
            a, b, c = args
            dac, dbc = self._distance(a, c), self._distance(b, c)
            if dac is None or dbc is None:
                return None
            v = dbc - dac
            return RelationFact(relation, args, decide(v, self.th.distance_margin), v, self.th.distance_margin)
        if relation == "angle":
            fa, fb = (self.nodes[int(x)].attributes.get("front") for x in args)
            v = None if fa is None or fb is None else angle_between(fa, fb)
            return RelationFact(relation, args, None if v is None else True, v or 0.0, self.th.angle_margin)
        if relation in SECTORS:
            a, b = args
            fb = self.nodes[int(b)].attributes.get("front")
            if fb is None:
                return RelationFact(relation, args, None, 0.0, self.th.sector_margin)
            ca = np.array(self.nodes[int(a)].attributes["center"][:2], float)
            cb = np.array(self.nodes[int(b)].attributes["center"][:2], float)
            theta = bearings(np.stack([ca, cb]), np.array([[np.nan, np.nan], fb], float))[0, 1]
            d = self._distance(a, b)
            code = sector_codes(np.array(theta), self.th.sector_margin, np.array(d is not None and d > 1e-6))[relation]
            return RelationFact(relation, args, holds_of(int(code)), float(theta), self.th.sector_margin)
        if relation == "between":
            return self._between_fact(*args)
        if relation == "free_space":
            sid, kind, *anchors = args
            for r in self.regions(kind, tuple(anchors)):
                if r.surface_id == sid:
                    return RelationFact(relation, args, True, r.area, self.th.free_min_area)
            return RelationFact(relation, args, False, 0.0, self.th.free_min_area)
        return self._facts.get(key)

    def facts_of(self, relation: str) -> list[RelationFact]:
        """The stored facts of one relation, in storage order (grouped once, on first use)."""
        return self._facts.facts_of(relation)

    def _margin(self, relation: str) -> float:
        return {"touching": self.th.touch_band, "far_from": self.th.far_from_band,
                "next_to": self.th.distance_margin}.get(relation, 0.0)

    def _distance(self, a, b) -> float | None:
        f = self._facts.get(("distance", (a, b))) or self._facts.get(("distance", (b, a)))
        return None if f is None else float(f.value)

    def _distance_matrix(self) -> np.ndarray:
        """Stored distances as a matrix over self.ids (inf where none is stored), from one pass over the facts:
        a pair stored either way round gives both entries, the (a, b) instance winning as _distance does."""
        if self._dist is None:
            n, pos = len(self.ids), self._pos
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

    def between_rows(self) -> dict[tuple[int, int], tuple[frozenset, frozenset]]:
        """{(b, c) ids with b < c: (ids A with between(A, b, c) true, ids undecided)}; every other A is False.
        The same arrays and rule as between_code, grouped per anchor pair for set-at-once lookups."""
        rows = {key: self.between_row(*key) for key in self._between_pairs()}
        return {key: (t, u) for key, (t, u) in rows.items() if t or u}

    def largest_between_row(self) -> int:
        """The most objects decided between any one anchor pair (0 when none)."""
        self._between_pairs()
        return max((len(t) for t, _u in self._brow.values()), default=0)

    def between_row(self, b: int, c: int) -> tuple[frozenset, frozenset]:
        """One entry of between_rows (b < c). Every anchor pair's row is built with the arrays (most rows
        are empty and share one constant), so a search trying many anchor pairs pays a dict lookup each."""
        self._between_pairs()
        return self._brow.get((b, c), _EMPTY_ROW)

    def _between_pairs(self) -> dict[tuple[int, int], int]:
        """(b, c) anchor ids -> row of the between arrays; also keeps the rows as sets (non-empty ones only)
        and the cells as lists for between_code."""
        if self._bpairs is None:
            arr = self._between_arrays()
            self._bpairs = {}
            if arr is not None:
                ids = self.ids
                B, C, cand, code, t = arr
                keys = [(ids[b], ids[c]) for b, c in zip(B.tolist(), C.tolist())]
                self._bpairs = {k: p for p, k in enumerate(keys)}
                rows: dict[int, tuple[list, list]] = {}
                P, A = np.nonzero(cand)
                for p, a, c in zip(P.tolist(), A.tolist(), code[P, A].tolist()):
                    r = rows.get(p)
                    if r is None:
                        r = rows[p] = ([], [])
                    r[0 if c == TRUE else 1].append(ids[a])
                for p, (yes, maybe) in rows.items():
                    self._brow[keys[p]] = (frozenset(yes), frozenset(maybe))
        return self._bpairs

    def _between_cells(self) -> tuple[list, list, list]:
        """The between arrays' candidate mask, code and t as lists (between_code reads single cells)."""
        if self._bcells is None:
            self._between_pairs()
            arr = self._between_arrays()
            self._bcells = ([], [], []) if arr is None else (arr[2].tolist(), arr[3].tolist(), arr[4].tolist())
        return self._bcells

    def _between_arrays(self):
        """between_arrays over the stored node centres and distances (kept: the table and the rows share it)."""
        if self._barr is _UNSET:
            self._barr = self._compute_between_arrays()
        return self._barr

    def _compute_between_arrays(self):
        xy = np.array([self.nodes[i].attributes["center"][:2] for i in self.ids], float).reshape(-1, 2)
        cats = [self.nodes[i].category for i in self.ids]
        return between_arrays(xy, np.array(self.ids), cats, self._distance_matrix(), self.th)

    def between_code(self, a: int, b: int, c: int) -> tuple[bool | None, float]:
        """(holds, t) of between(a, b, c) for three distinct known ids, without building a RelationFact
        (the QA index's hot path; the same arrays and rule as between_table: an object off the anchor
        pair's candidate mask is False with t = 0)."""
        pairs = self._between_pairs()
        b, c = int(b), int(c)
        p = pairs.get((b, c) if b < c else (c, b))
        if p is None:
            return False, 0.0
        i = self._pos[int(a)]
        cand, code, t = self._between_cells()
        if not cand[p][i]:
            return False, 0.0
        return holds_of(code[p][i]), t[p][i]

    def _between_fact(self, a, b, c) -> RelationFact | None:
        h, t = self.between_code(a, b, c)
        return RelationFact("between", (a, b, c), h, t, self.th.between_t_margin)

    # ------------------------------------------------------------------ enumeration
    def instances(self, relation: str, decided_only: bool = True) -> Iterator[RelationFact]:
        """Every evaluated instance of `relation` (mirrors and derived ones included), deterministic order."""
        rel = REGISTRY[relation]
        if relation == "free_space":
            for r in self.graph.free_space:
                yield RelationFact(relation, (r.surface_id, r.kind, *r.anchors), True, r.area, self.th.free_min_area)
            return
        if relation in ("corner", "edge"):
            key = "corners" if relation == "corner" else "edges"
            arg_sets = [(i, sid, lab) for i in self.ids for sid, e in sorted(self.surfaces.items()) for lab in e.get(key, [])]
        elif relation in ("on", "supported_by"):
            arg_sets = []
            for i in self.ids:
                s = self.nodes[i].support
                if s is not None:
                    arg_sets.append((i, int(s[4:]) if s.startswith("obj:") else s))
        elif rel.arity == 1:
            arg_sets = [(i,) for i in self.ids]
        elif rel.arity == 2:
            arg_sets = list(permutations(self.ids, 2))
        else:
            arg_sets = list(permutations(self.ids, 3))
        for args in arg_sets:
            f = self.fact(relation, *args)
            if f is not None and (f.holds is not None or not decided_only):
                yield f
