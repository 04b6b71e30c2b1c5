"""Per-frame lookup tables the executor needs, built once per (frame, scene graph).

Why: instantiating templates is thousands of small lookups (is the cup left of the plate? which objects
are boxes?). Doing them against tables prepared once per sample is most of the engine's speed (figures
in docs/templates.md). Relation truth comes only from the scene graph's facts (through the graph's own
query index, which knows the storage and mirror conventions); this module adds no geometry of relations.
"""

from __future__ import annotations

import math
from bisect import bisect_right
from itertools import accumulate
from typing import Any, NamedTuple

import numpy as np

from refspatial_gen.core.mask import denormalise_point
from refspatial_gen.core.model import FreeSpaceRegion, Frame, SceneGraph
from refspatial_gen.graph.relations.base import decide


# size relations the graph derives from node attributes: relation -> (base relation, arguments swapped)
_DERIVED_OF = {"tall": ("tall", False), "short": ("tall", True), "big": ("big", False), "small": ("big", True),
               "wide": ("wide", False), "thin": ("wide", True)}


# antisymmetric relations stored once per pair: relation -> (stored base relation, arguments swapped)
_PAIR_OF = {"left": ("left", False), "right": ("left", True), "front": ("front", False), "behind": ("front", True),
            "above_image": ("above_image", False), "below_image": ("above_image", True),
            "above_world": ("above_world", False), "below_world": ("above_world", True)}
_MISS = object()
NO_FACT = object()  # decision(): the relation was not evaluated for these arguments
_EMPTY: frozenset = frozenset()
_EMPTY_ENTRY: tuple[frozenset, frozenset, frozenset] = (_EMPTY, _EMPTY, _EMPTY)
_INF = float("inf")
_HOLDS = (False, True, None, None)
_PAIR_CODES = {True: (1, 0), False: (0, 1), None: (2, 2)}  # stored holds -> codes of (a, b) and (b, a)  # holds by table code (1 true, 0 false, 2 undecided; 3 = not stored)
# stored-sparse binary relations whose whole table the index builds from the stored facts (absent-instance
# rules of GraphIndex._lookup): symmetric ones are stored once per pair
_SPARSE = frozenset({"inside", "facing", "facing_away", "far_from", "touching", "next_to"})
_SYMMETRIC = frozenset({"far_from", "touching", "next_to"})  # fact-cache sentinel (None is a cached "not evaluated")


class Reject(Exception):
    """An instantiation is unusable (empty set, undecided relation, missing fact...). `reason` is counted."""

    def __init__(self, reason: str) -> None:
        super().__init__(reason)
        self.reason = reason


class Fact(NamedTuple):
    """A relation's decision and value (a NamedTuple: built hundreds of times per sample, cheaply)."""

    holds: bool | None
    value: float


class SceneIndex:
    """Objects, phrases, attributes, facts and free-space regions of one frame, ready for fast lookup."""

    def __init__(self, frame: Frame, graph: SceneGraph) -> None:
        from refspatial_gen.graph.query import GraphIndex

        self.frame, self.graph = frame, graph
        self.W, self.H = frame.camera.width, frame.camera.height
        # one pass over the nodes fills the per-object tables (built for every sample: kept cheap)
        nodes: dict = {}
        phrase: dict[int, str] = {}
        phrases: list[str] = []
        points: dict[int, tuple[float, float]] = {}
        category: dict[int, str] = {}
        color: dict[int, str | None] = {}
        on: dict[int, frozenset] = {}
        for n in graph.nodes:
            i = n.object_id
            nodes[i] = n
            if n.phrases:
                phrase[i] = n.phrases[0]
                phrases.extend(n.phrases)
            if n.point is not None:
                points[i] = (float(n.point[0]), float(n.point[1]))
            category[i] = n.category
            a = n.attributes
            color[i] = a.get("color") or a.get("colour")
            # "on the table": the root surface an object stands on (directly or stacked), or its direct support
            root, sup = a.get("surface"), n.support
            on[i] = frozenset((root, sup) if root and sup else (root,) if root else (sup,) if sup else ())
        self.nodes, self.phrase, self.category, self.color, self.on = nodes, phrase, category, color, on
        self.ids: tuple[int, ...] = tuple(sorted(nodes))
        self.objects = {o.id: o for o in frame.objects}
        self.phrase_set = frozenset(phrases)  # every phrase that names a node
        self.answer_points = points  # object -> answer point (normalised), for objects that have one
        self.referable: tuple[int, ...] = tuple(i for i in self.ids if i in phrase and i in points)
        self.categories = tuple(sorted(set(category.values())))
        self.colors = tuple(sorted({c for c in color.values() if c}))
        self.surfaces = {s.id: s for s in frame.surfaces}
        self.has_front = {i: (i in self.objects and self.objects[i].front is not None) for i in self.ids}
        self.region_list: tuple[FreeSpaceRegion, ...] = tuple(graph.free_space)
        # (kind, anchors) -> the first region listed with them (reversed: later duplicates are overwritten)
        self.regions: dict[tuple, FreeSpaceRegion] = {(r.kind, tuple(r.anchors)): r for r in reversed(self.region_list)}
        self.has_between_region = any(r.kind == "between" for r in self.region_list)
        labels = graph.meta.get("surfaces") or {}
        self.spots: tuple[tuple[str, str, str], ...] = tuple(sorted(
            (kind, sid, lab) for sid, e in labels.items() if sid in self.surfaces
            for kind, key in (("corner", "corners"), ("edge", "edges")) for lab in e.get(key, [])))
        self.gindex = GraphIndex(graph, frame)
        self._fact_cache: dict[tuple, Fact | None] = {}
        self._rel_sets: dict[tuple, tuple[frozenset, frozenset, frozenset]] = {}
        self._cols: dict[str, list | None] = {}  # relation -> codes per anchor position (_table_cols)
        self._codes: dict[str, list | None] = {}
        self._pos = {x: k for k, x in enumerate(self.ids)}
        self._dist: list | None = None
        self._derived: dict[str, tuple | None] = {}
        self._pairs: dict[str, list] = {}  # pair relation base -> code rows (_pair_codes)
        self._pair_vals: dict[str, list] = {}
        self._runs: dict[int, list[int]] = {}
        self._sizes: dict[int, tuple[float, float, float]] = {}
        self._key_points: dict[int, list[float]] = {}
        self._cam_rows: list | None = None
        self._region_rounded: dict[int, tuple] = {}
        self._has_true_spot: bool | None = None
        self._largest_between_row: int | None = None
        # executor: slot signature (executor.slot_signature) -> unshuffled candidates in this frame
        self.slot_memo: dict[tuple, tuple] = {}
        groups: dict = {}
        for i in self.ids:
            groups.setdefault(("category", category[i]), []).append(i)
            groups.setdefault(("color", color[i]), []).append(i)
        self.by_category: dict[str, frozenset[int]] = {c: frozenset(groups[("category", c)]) for c in self.categories}
        self.by_color: dict[str, frozenset[int]] = {c: frozenset(groups[("color", c)]) for c in self.colors}
        self.all = frozenset(self.ids)

    # ------------------------------------------------------------------ facts
    def _derived_tables(self, base: str) -> tuple[list, list, list] | None:
        """(code rows, None, value rows) of a size comparison over self.ids, with the graph's own decision
        function on the stored node attributes (what GraphIndex derives one pair at a time; a test pins the
        equality). None without gravity or thresholds. The three comparisons (tall, big, wide) are computed
        together on first use: one set of array operations instead of three."""
        if base not in self._derived:
            from refspatial_gen.graph.relations.common import TRUE, UNDECIDED
            from refspatial_gen.graph.relations.sizes import DERIVED, compare

            th, ids = self.gindex.th, self.ids
            if th is None or not self.gindex.world or not ids:
                for b in DERIVED:
                    self._derived[b] = None
                return None
            bases = list(DERIVED)
            q = np.array([[self.nodes[i].attributes[DERIVED[b][0]] for i in ids] for b in bases], float)
            absm = np.array([getattr(th, DERIVED[b][1]) if DERIVED[b][1] else 0.0 for b in bases])[:, None, None]
            relm = np.array([getattr(th, DERIVED[b][2]) for b in bases])[:, None, None]
            v, codes, _m = compare(q, absm, relm)  # the graph's rule, the three quantities stacked
            # graph codes TRUE 1 / FALSE 0 / UNDECIDED -1 -> ours 1 / 0 / 2 (floor modulo 3)
            assert (TRUE, UNDECIDED) == (1, -1)
            ours = np.mod(np.asarray(codes, dtype=np.int8), 3)
            n = len(ids)
            ours[:, np.arange(n), np.arange(n)] = 3
            rows, vals = ours.tolist(), v.tolist()  # python values: no per-element numpy
            for k, b in enumerate(bases):
                self._derived[b] = (rows[k], None, vals[k])
        return self._derived[base]

    def _pair_codes(self, base: str) -> list:
        """Code rows of a stored antisymmetric relation in both directions over self.ids: R(b, a) = not R(a, b)
        (the storage rule of graph.query; a test pins the equality with GraphIndex). Code 3 = not stored."""
        codes = self._pairs.get(base)
        if codes is None:
            pos = self._pos
            n = len(self.ids)
            codes = [[3] * n for _ in range(n)]
            for f in self.facts_of(base):
                args = f.args
                if len(args) == 2:
                    i, j = pos.get(args[0]), pos.get(args[1])
                    if i is not None and j is not None and i != j:
                        codes[i][j], codes[j][i] = _PAIR_CODES[f.holds]
            self._pairs[base] = codes
        return codes

    def _pair_values(self, base: str) -> list:
        """Value rows to _pair_codes: the stored value, negated for the reversed pair (fact() needs them; the
        search's decisions do not, so they are built only when a Fact is asked for)."""
        vals = self._pair_vals.get(base)
        if vals is None:
            pos = self._pos
            n = len(self.ids)
            vals = [[0.0] * n for _ in range(n)]
            for f in self.facts_of(base):
                args = f.args
                if len(args) == 2:
                    i, j = pos.get(args[0]), pos.get(args[1])
                    if i is not None and j is not None and i != j:
                        v = float(f.value)
                        vals[i][j], vals[j][i] = v, -v
            self._pair_vals[base] = vals
        return vals

    def fact(self, relation: str, args: tuple) -> Fact | None:
        key = (relation, args)
        f = self._fact_cache.get(key, _MISS)
        if f is not _MISS:
            return f
        pair = _PAIR_OF.get(relation)
        pos = self._pos
        if pair is not None and (pair[0] != "above_world" or self.gindex.world) and len(args) == 2:
            cl = self._pair_codes(pair[0])
            a, b = args[::-1] if pair[1] else args
            i, j = pos.get(a), pos.get(b)
            if i is not None and j is not None and cl[i][j] != 3:
                f = self._fact_cache[key] = Fact(_HOLDS[cl[i][j]], self._pair_values(pair[0])[i][j])
                return f
        base = _DERIVED_OF.get(relation)
        if base is not None:
            tab = self._derived_tables(base[0])
            out = None
            if tab is not None and len(args) == 2:
                a, b = args[::-1] if base[1] else args
                i, j = pos.get(a), pos.get(b)
                if i is not None and j is not None and i != j:
                    out = Fact(_HOLDS[tab[0][i][j]], tab[2][i][j])
            self._fact_cache[key] = out
            return out
        if (relation == "corner" or relation == "edge") and len(args) == 3:
            out = self._spot_fact(relation, args)
            self._fact_cache[key] = out
            return out
        if (relation == "close" or relation == "far") and self._between_ok(args):
            out = self._close_fact(*args) if relation == "close" else self._close_fact(args[1], args[0], args[2])
            self._fact_cache[key] = out
            return out
        if relation == "between" and self._between_ok(args):
            h, t = self.gindex.between_code(*args)
            out = Fact(h, float(t))
            self._fact_cache[key] = out
            return out
        out = self._general_fact(relation, args)
        self._fact_cache[key] = out
        return out

    def between_entry(self, b: int, c: int) -> tuple[frozenset, frozenset, frozenset]:
        """(objects x with between(x, b, c) true, undecided, not evaluated), b and c excluded; the whole row for
        the anchor pair is looked up once and kept (the executor's `between` op asks it for many sets)."""
        key = ("between", b, c)
        entry = self._rel_sets.get(key)
        if entry is None and self.gindex.world and b != c and type(b) is int and type(c) is int \
                and b in self.nodes and c in self.nodes:
            # whole row from the graph index's grouped table: a fact for every other object, absent = False
            t, u = self.gindex.between_row(b, c) if b < c else self.gindex.between_row(c, b)
            entry = self._rel_sets[key] = (t, u, _EMPTY) if t or u else _EMPTY_ENTRY
        if entry is None:
            true, undecided, missing = set(), set(), set()
            for x in self.ids:
                if x == b or x == c:
                    continue
                f = self.fact("between", (x, b, c))
                if f is None:
                    missing.add(x)
                elif f.holds is None:
                    undecided.add(x)
                elif f.holds:
                    true.add(x)
            entry = (frozenset(true), frozenset(undecided), frozenset(missing))
            self._rel_sets[key] = entry
        return entry

    def between(self, b: int, c: int, s: frozenset) -> frozenset:
        """Objects x of `s` (b and c excluded) with between(x, b, c) true; Reject("margin") when one of them is
        undecided, Reject("no_fact") when one was not evaluated."""
        true, undecided, missing = self.between_entry(b, c)
        if (undecided and not undecided.isdisjoint(s)) or (missing and not missing.isdisjoint(s)):
            for x in s:  # the first bad member in the set's order names the reason, as a member-wise loop would
                if x != b and x != c:
                    self.holds("between", (x, b, c))
        return s & true

    def _between_ok(self, args: tuple) -> bool:
        """The cases where GraphIndex.fact("between", ...) reaches its table (three distinct known objects,
        gravity known); anything else takes the general path and its None."""
        if len(args) != 3 or not self.gindex.world:
            return False
        a, b, c = args
        nodes = self.nodes
        return (a != b and a != c and b != c and type(a) is int and type(b) is int and type(c) is int
                and a in nodes and b in nodes and c in nodes)

    def _spot_rule(self, relation: str, args: tuple) -> Any:
        """corner/edge(a, surface, label) by GraphIndex's rule without building RelationFacts: the stored
        instance, else False when a stands on that surface and the surface has that label, else None (not
        evaluated); _MISS when the arguments are not a known object and a labelled spot (general path)."""
        a, sid, label = args
        if type(a) is not int or a not in self.nodes or not self.gindex.world or len({a, sid, label}) < 3:
            return _MISS
        f = self.gindex._facts.get((relation, args))
        if f is not None:
            return f
        labels = self.gindex.surfaces.get(sid, {}).get("corners" if relation == "corner" else "edges", [])
        if self.nodes[a].attributes.get("surface") != sid or label not in labels:
            return None
        return False

    def _spot_fact(self, relation: str, args: tuple) -> Fact | None:
        r = self._spot_rule(relation, args)
        if r is _MISS:
            return self._general_fact(relation, args)
        if r is None or r is False:
            return None if r is None else Fact(False, 0.0)
        return Fact(r.holds, float(r.value))

    def _general_fact(self, relation: str, args: tuple) -> Fact | None:
        f = self.gindex.fact(relation, *args)
        return None if f is None else Fact(f.holds, float(f.value))

    def _close_fact(self, a: int, b: int, c: int) -> Fact | None:
        """close(a, b, c): a is closer to c than b is (value d(b, c) - d(a, c)); far(a, b, c) = close(b, a, c).
        The rule of GraphIndex._lookup, on the same stored distances, without building a RelationFact."""
        d = self._dist
        if d is None:
            d = self._dist = self.gindex._distance_matrix().tolist()
        pos = self._pos
        dac, dbc = d[pos[a]][pos[c]], d[pos[b]][pos[c]]
        if dac == _INF or dbc == _INF:
            return None
        v = dbc - dac
        return Fact(decide(v, self.gindex.th.distance_margin), v)

    @property
    def distance_margin(self) -> float:
        return self.gindex.th.distance_margin

    def distances_to(self, anchor: int, objects: list) -> list[float] | None:
        """Stored distances of `objects` to `anchor` (the ones close/far compare), or None when close/far would
        not come from them (no gravity, an unknown or repeated object, a missing distance): the caller then
        takes the fact-by-fact path."""
        if not self.gindex.world or type(anchor) is not int or anchor not in self._pos:
            return None
        d = self._dist
        if d is None:
            d = self._dist = self.gindex._distance_matrix().tolist()
        pos, c = self._pos, self._pos[anchor]
        out = []
        for x in objects:
            i = pos.get(x) if type(x) is int else None
            if i is None or i == c:
                return None
            v = d[i][c]
            if v == _INF:
                return None
            out.append(v)
        return out

    def decision(self, relation: str, args: tuple) -> Any:
        """fact(relation, args).holds (True, False, None = undecided), or NO_FACT when it was not evaluated.
        Binary relations with a whole table (the ones rel_entry reads) answer from the table without building
        a Fact; tests pin the tables against the fact path."""
        if len(args) == 2:
            cols = self._cols.get(relation, _MISS)
            if cols is _MISS:
                cols = self._cols[relation] = self._table_cols(relation)
            if cols is not None:
                pos = self._pos
                i, j = pos.get(args[1]), pos.get(args[0])  # cols[anchor][x] codes relation(x, anchor)
                if i is not None and j is not None and i != j:
                    c = cols[i][j]
                    if c != 3:
                        return _HOLDS[c]
        elif (relation == "corner" or relation == "edge") and len(args) == 3:
            r = self._spot_rule(relation, args)
            if r is not _MISS:
                return NO_FACT if r is None else (False if r is False else r.holds)
        f = self.fact(relation, args)
        return NO_FACT if f is None else f.holds

    def holds(self, relation: str, args: tuple) -> bool:
        """True/False; raises Reject("margin") when undecided and Reject("no_fact") when not evaluated."""
        h = self.decision(relation, args)
        if h is True or h is False:
            return h
        raise Reject("margin" if h is None else "no_fact")

    def value(self, relation: str, args: tuple) -> float:
        f = self.fact(relation, args)
        if f is None:
            raise Reject("no_fact")
        return f.value

    def rel_entry(self, relation: str, anchor: int) -> tuple[frozenset, frozenset, frozenset]:
        """(objects x with relation(x, anchor) true, undecided, not evaluated), anchor excluded; built once
        per (relation, anchor) and kept (the search asks it for many sets). Relations with a whole-matrix
        path (stored pairs, size comparisons) fill every anchor's entry at once."""
        key = (relation, anchor)
        entry = self._rel_sets.get(key)
        if entry is None:
            cols = self._cols.get(relation, _MISS)
            if cols is _MISS:
                cols = self._cols[relation] = self._table_cols(relation)
            pos = self._pos.get(anchor) if cols is not None else None
            entry = self._rel_sets[key] = self._entry_of(relation, anchor, None if pos is None else cols[pos])
        return entry

    def _entry_of(self, relation: str, anchor: int, codes: list | None) -> tuple[frozenset, frozenset, frozenset]:
        """One anchor's entry, from a row of holds codes (1 true, 0 false, 2 undecided, 3 not stored) over
        self.ids, or fact by fact when `codes` is None; a code 3 asks fact() (the general path decides)."""
        ids = self.ids
        if codes is not None:
            k = self._pos[anchor]
            if codes.count(3) == (codes[k] == 3):  # no off-anchor code asks the general path: comprehensions
                t = frozenset([x for x, c in zip(ids, codes) if c == 1 and x != anchor])
                if 2 not in codes:
                    return t, _EMPTY, _EMPTY
                return t, frozenset([x for x, c in zip(ids, codes) if c == 2 and x != anchor]), _EMPTY
        true, undecided, missing = [], [], []
        cache, fact = self._fact_cache, self.fact
        for k, x in enumerate(ids):
            if x == anchor:
                continue
            c = 3 if codes is None else codes[k]
            if c == 1:
                true.append(x)
            elif c == 2:
                undecided.append(x)
            elif c == 3:
                f = cache.get((relation, (x, anchor)), _MISS)
                if f is _MISS:
                    f = fact(relation, (x, anchor))
                if f is None:
                    missing.append(x)
                elif f.holds is None:
                    undecided.append(x)
                elif f.holds:
                    true.append(x)
        return frozenset(true), frozenset(undecided), frozenset(missing)

    def _table_cols(self, relation: str) -> list | None:
        """Per anchor position, the codes of relation(x, anchor) over self.ids, for relations with a
        whole-matrix path (stored pairs, sparse stored relations, size comparisons); None otherwise."""
        mat = None
        pair = _PAIR_OF.get(relation)
        if pair is not None and (pair[0] != "above_world" or self.gindex.world):
            mat, swap = self._pair_codes(pair[0]), pair[1]
        elif relation in _SPARSE or relation == "outside":
            mat, swap = self._sparse_codes(relation), False
        else:
            d = _DERIVED_OF.get(relation)
            if d is not None:
                tab = self._derived_tables(d[0])
                mat, swap = (None if tab is None else tab[0]), d[1]
        if mat is None:
            return None
        # relation(x, anchor) = base(x, anchor): column of the anchor; swapped: base(anchor, x), its row
        return mat if swap else [list(col) for col in zip(*mat)]

    def facts_of(self, relation: str) -> list:
        """The graph's stored facts of one relation (grouped once, by the graph index)."""
        return self.gindex.facts_of(relation)

    def _sparse_codes(self, relation: str) -> list | None:
        """Code rows of a sparse stored relation (or outside = not inside) over self.ids, with GraphIndex._lookup's
        rule for absent instances: inside False; facing/facing_away False, or undecided when A has no front;
        far_from/touching/next_to stored in either direction, else False when the pair has a distance."""
        if relation in self._codes:
            return self._codes[relation]
        out = None
        if self.gindex.world:
            n, pos = len(self.ids), self._pos
            if relation == "outside":
                flip = (1, 0, 2, 3)
                out = [[flip[c] for c in row] for row in self._sparse_codes("inside")]
            else:
                if relation == "inside":
                    out = [[0] * n for _ in range(n)]
                elif relation in _SYMMETRIC:
                    if self._dist is None:
                        self._dist = self.gindex._distance_matrix().tolist()
                    out = [[3 if d == _INF else 0 for d in row] for row in self._dist]
                else:  # facing, facing_away
                    out = [[2 if self.nodes[i].attributes.get("front") is None else 0] * n for i in self.ids]
                direct = []
                for f in self.facts_of(relation):
                    if len(f.args) == 2:
                        a, b = f.args
                        if a in pos and b in pos and a != b:
                            h = f.holds
                            direct.append((pos[a], pos[b], 2 if h is None else int(bool(h))))
                if relation in _SYMMETRIC:  # a reversed stored instance counts unless the pair is stored as asked
                    for i, j, c in direct:
                        out[j][i] = c
                for i, j, c in direct:
                    out[i][j] = c
        self._codes[relation] = out
        return out

    def narrow(self, relation: str, anchor: int, s: frozenset) -> frozenset:
        """Objects of `s` (anchor excluded) for which relation(x, anchor) holds. Raises Reject("margin")
        when one of them is undecided and Reject("no_fact") when the relation was not evaluated for one."""
        true, undecided, missing = self.rel_entry(relation, anchor)
        if undecided and not undecided.isdisjoint(s):
            raise Reject("margin")
        if missing and not missing.isdisjoint(s):
            raise Reject("no_fact")
        return s & true

    # ------------------------------------------------------------------ points and masks
    def point(self, object_id: int) -> tuple[float, float]:
        p = self.nodes[object_id].point
        if p is None:
            raise Reject("no_point")
        return (float(p[0]), float(p[1]))

    def point_in_mask(self, object_id: int, point: tuple[float, float]) -> bool:
        """Is the pixel a normalised point falls in part of the object's visible mask (RLE, no decode)."""
        o = self.objects.get(object_id)
        if o is None or o.mask is None:
            return False
        runs = self._runs.get(object_id)
        if runs is None:
            runs = self._runs[object_id] = list(accumulate(o.mask.counts))  # run ends, column-major
        x, y = denormalise_point(point[0], point[1], self.W, self.H)
        return bisect_right(runs, x * o.mask.height + y) % 2 == 1

    @property
    def has_true_spot(self) -> bool:
        """Is any object at a corner or edge (a stored corner/edge instance that holds)? decision() answers True
        only from such an instance, so without one an `at` step keeps nothing."""
        v = self._has_true_spot
        if v is None:
            v = self._has_true_spot = any(f.holds is True for rel in ("corner", "edge") for f in self.facts_of(rel))
        return v

    @property
    def largest_between_row(self) -> int:
        """The most objects between any anchor pair (decided true). A `between` step's output is a subset of
        its anchor pair's row, so a step bound to keep more than this rejects every binding."""
        v = self._largest_between_row
        if v is None:
            v = self._largest_between_row = self.gindex.largest_between_row() if self.gindex.world else 0
        return v

    def region_rounded(self, region: FreeSpaceRegion) -> tuple[tuple, tuple]:
        """A free-space region's polygon (5 decimals) and world point (6 decimals) as answers record them,
        rounded once per region and sample (callers copy before storing)."""
        hit = self._region_rounded.get(id(region))
        if hit is None or hit[0] is not region:
            poly = tuple((round(float(x), 5), round(float(y), 5)) for x, y in region.polygon_xy)
            hit = self._region_rounded[id(region)] = (region, poly, tuple(round(float(x), 6) for x in region.point_world))
        return hit[1], hit[2]

    def key_point(self, object_id: int) -> list[float]:
        """The object's answer point rounded as key steps store it (render.round_key), a fresh list each call."""
        p = self._key_points.get(object_id)
        if p is None:
            x, y = self.point(object_id)
            p = self._key_points[object_id] = [round(x, 3), round(y, 3)]
        return list(p)

    def size(self, object_id: int) -> tuple[float, float, float]:
        """(larger horizontal extent, smaller horizontal extent, height) in metres, from the 3D box: the
        footprint's edge lengths and the box's vertical extent, in closed form (no corner arrays)."""
        out = self._sizes.get(object_id)
        if out is None:
            b = self.objects[object_id].box
            (r00, r01, r02), (r10, r11, r12), (r20, r21, r22) = b.rotation.tolist()
            sx, sy, sz = b.size.tolist()
            e0, e1 = math.hypot(sx * r00, sx * r10), math.hypot(sy * r01, sy * r11)
            h = abs(r20) * sx + abs(r21) * sy + abs(r22) * sz
            out = self._sizes[object_id] = (max(e0, e1), min(e0, e1), h)
        return out

    def front_cam(self, object_id: int) -> tuple[float, float, float]:
        """The object's semantic front as a unit vector in camera coordinates."""
        o = self.objects[object_id]
        fw = o.front_world
        if fw is None:
            raise Reject("no_front")
        R = self._cam_rows
        if R is None:
            R = self._cam_rows = self.frame.camera.world_from_cam[:3, :3].tolist()
        f0, f1, f2 = (float(x) for x in fw)
        # R.T @ fw, then unit length (three-vector arithmetic in Python: no array round trip)
        v = [R[0][i] * f0 + R[1][i] * f1 + R[2][i] * f2 for i in range(3)]
        n = math.sqrt(v[0] * v[0] + v[1] * v[1] + v[2] * v[2])
        return v[0] / n, v[1] / n, v[2] / n
