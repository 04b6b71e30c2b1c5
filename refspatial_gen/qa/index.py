"""Per-frame lookup tables the executor needs, built once per (frame, scene graph).

Why: instantiating templates is thousands of small lookups (is the cup left of the plate? which objects
are boxes?). Doing them against tables prepared once per sample is most of the engine's speed (figures
in docs/templates.md). Relation truth comes only from the scene graph's stored facts, through the graph's
relation tables (graph/tables.py, which apply each relation's own storage rules); this module keeps the
per-object tables (phrases, points, categories, colours, supports, regions) and caches the lookups of one
sample.
"""

from __future__ import annotations

import math
from bisect import bisect_right
from itertools import accumulate
from typing import Any

from refspatial_gen.core.mask import denormalise_point
from refspatial_gen.core.model import Frame, FreeSpaceRegion, Node, SceneGraph
from refspatial_gen.graph.relations.base import HOLDS_OF_CODE, Cell
from refspatial_gen.graph.relations.distances import linked, nested
from refspatial_gen.graph.tables import RelationTables
from refspatial_gen.qa.ops.base import REGION_KINDS

_MISS = object()
NO_FACT = object()  # decision(): the relation was not evaluated for these arguments
_EMPTY: frozenset[int] = frozenset()
_EMPTY_ENTRY: tuple[frozenset[int], frozenset[int], frozenset[int]] = (_EMPTY, _EMPTY, _EMPTY)
_INF = float("inf")
_HOLDS = HOLDS_OF_CODE  # table code -> holds (1 true, 0 false, 2 undecided; 3 = not evaluated)
Fact = Cell  # a looked-up instance: holds, value, margin
Entry = tuple[frozenset[int], frozenset[int], frozenset[int]]


class Reject(Exception):
    """An instantiation is unusable (empty set, undecided relation, missing fact...). `reason` is counted."""

    def __init__(self, reason: str) -> None:
        super().__init__(reason)
        self.reason = reason


class SceneIndex:
    """Objects, phrases, attributes, facts and free-space regions of one frame, ready for fast lookup."""

    def __init__(self, frame: Frame, graph: SceneGraph) -> None:
        self.frame, self.graph = frame, graph
        self.W, self.H = frame.camera.width, frame.camera.height
        # one pass over the nodes fills the per-object tables (built for every sample: kept cheap)
        nodes: dict[int, Node] = {}
        phrase: dict[int, str] = {}
        phrases: list[str] = []
        points: dict[int, tuple[float, float]] = {}
        category: dict[int, str] = {}
        color: dict[int, str | None] = {}
        on: dict[int, frozenset[Any]] = {}
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
        self.regions: dict[tuple[Any, ...], FreeSpaceRegion] = {
            (r.kind, tuple(r.anchors)): r for r in reversed(self.region_list)
        }
        self.has_between_region = any(r.kind == "between" for r in self.region_list)
        labels = graph.meta.get("surfaces") or {}
        self.spots: tuple[tuple[str, str, str], ...] = tuple(
            sorted(
                (kind, sid, lab)
                for sid, e in labels.items()
                if sid in self.surfaces
                for kind, key in (("corner", "corners"), ("edge", "edges"))
                for lab in e.get(key, [])
            )
        )
        self.tables = RelationTables(graph)  # relation truth: the graph's stored facts, by each relation's rules
        self.world = self.tables.world
        self._fact_cache: dict[tuple[str, tuple[Any, ...]], Fact | None] = {}
        self._rel_sets: dict[tuple[Any, ...], Entry] = {}
        self._cols: dict[str, list[list[int]] | None] = {}  # relation -> codes per anchor position
        self._pos = self.tables.pos
        self._runs: dict[int, list[int]] = {}
        self._sizes: dict[int, tuple[float, float, float]] = {}
        self._key_points: dict[int, list[float]] = {}
        self._cam_rows: list[Any] | None = None
        self._region_rounded: dict[int, tuple[Any, ...]] = {}
        self._has_true_spot: bool | None = None
        self._largest_between_row: int | None = None
        # executor: slot signature (executor.slot_signature) -> unshuffled candidates in this frame
        self.slot_memo: dict[tuple[Any, ...], tuple[Any, ...]] = {}
        groups: dict[tuple[str, Any], list[int]] = {}
        for i in self.ids:
            groups.setdefault(("category", category[i]), []).append(i)
            groups.setdefault(("color", color[i]), []).append(i)
        self.by_category: dict[str, frozenset[int]] = {c: frozenset(groups[("category", c)]) for c in self.categories}
        self.by_color: dict[str, frozenset[int]] = {c: frozenset(groups[("color", c)]) for c in self.colors}
        self.all = frozenset(self.ids)

    # ------------------------------------------------------------------ facts
    def fact(self, relation: str, args: tuple[Any, ...]) -> Fact | None:
        """The instance (holds, value, margin), or None when it was not evaluated; kept for the sample."""
        key = (relation, args)
        f = self._fact_cache.get(key, _MISS)
        if f is _MISS:
            f = self._fact_cache[key] = self.tables.cell(relation, args)
        return f  # type: ignore[return-value]

    def _columns(self, relation: str) -> list[list[int]] | None:
        cols = self._cols.get(relation, _MISS)
        if cols is _MISS:
            cols = self._cols[relation] = self.tables.columns(relation)
        return cols  # type: ignore[return-value]

    def decision(self, relation: str, args: tuple[Any, ...]) -> Any:
        """fact(relation, args).holds (True, False, None = undecided), or NO_FACT when it was not evaluated.
        Binary relations with a whole table answer from the table without building a Fact."""
        if len(args) == 2:
            cols = self._cols.get(relation, _MISS)
            if cols is _MISS:
                cols = self._columns(relation)
            if cols is not None:
                pos = self._pos
                i, j = pos.get(args[1]), pos.get(args[0])  # cols[anchor][x] codes relation(x, anchor)
                if i is not None and j is not None and i != j:
                    c = cols[i][j]  # type: ignore[index]
                    if c != 3:
                        return _HOLDS[c]
        f = self.fact(relation, args)
        return NO_FACT if f is None else f.holds

    def holds(self, relation: str, args: tuple[Any, ...]) -> bool:
        """True/False; raises Reject("margin") when undecided and Reject("no_fact") when not evaluated."""
        h = self.decision(relation, args)
        if h is True or h is False:
            return h
        raise Reject("margin" if h is None else "no_fact")

    def value(self, relation: str, args: tuple[Any, ...]) -> float:
        f = self.fact(relation, args)
        if f is None:
            raise Reject("no_fact")
        return f.value

    def facts_of(self, relation: str) -> list[Any]:
        """The graph's stored facts of one relation."""
        return self.tables.facts_of(relation)

    # ------------------------------------------------------------------ sets of objects
    def rel_entry(self, relation: str, anchor: int) -> Entry:
        """(objects x with relation(x, anchor) true, undecided, not evaluated), anchor excluded; built once
        per (relation, anchor) and kept (the search asks it for many sets). Relations with a whole table
        (stored pairs, sparse relations, size comparisons) read the anchor's column."""
        key = (relation, anchor)
        entry = self._rel_sets.get(key)
        if entry is None:
            cols = self._cols.get(relation, _MISS)
            if cols is _MISS:
                cols = self._columns(relation)
            pos = self._pos.get(anchor) if cols is not None else None
            entry = self._rel_sets[key] = self._entry_of(relation, anchor, None if pos is None else cols[pos])  # type: ignore[index]
        return entry

    def _entry_of(self, relation: str, anchor: int, codes: list[int] | None) -> Entry:
        """One anchor's entry, from a column of table codes (1 true, 0 false, 2 undecided, 3 not evaluated)
        over self.ids, or fact by fact when `codes` is None; a code 3 asks fact() (the cell rule decides)."""
        ids = self.ids
        if codes is not None:
            k = self._pos[anchor]
            if codes.count(3) == (codes[k] == 3):  # no off-anchor code asks the cell rule: comprehensions
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
                elif f.holds is None:  # type: ignore[attr-defined]
                    undecided.append(x)
                elif f.holds:  # type: ignore[attr-defined]
                    true.append(x)
        return frozenset(true), frozenset(undecided), frozenset(missing)

    def narrow(self, relation: str, anchor: int, s: frozenset[int]) -> frozenset[int]:
        """Objects of `s` (anchor excluded) for which relation(x, anchor) holds. Raises Reject("margin")
        when one of them is undecided and Reject("no_fact") when the relation was not evaluated for one."""
        true, undecided, missing = self.rel_entry(relation, anchor)
        if undecided and not undecided.isdisjoint(s):
            raise Reject("margin")
        if missing and not missing.isdisjoint(s):
            raise Reject("no_fact")
        return s & true

    def between_entry(self, b: int, c: int) -> Entry:
        """(objects x with between(x, b, c) true, undecided, not evaluated), b and c excluded; the whole row for
        the anchor pair is looked up once and kept (the `between` op asks it for many sets)."""
        key = ("between", b, c)
        entry = self._rel_sets.get(key)
        if (
            entry is None
            and self.world
            and b != c
            and type(b) is int
            and type(c) is int
            and b in self.nodes
            and c in self.nodes
        ):
            table = self.tables.table("between")
            if table is not None:  # a fact for every other object: absent = False
                t, u = table.row(b, c) if b < c else table.row(c, b)
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

    def between(self, b: int, c: int, s: frozenset[int]) -> frozenset[int]:
        """Objects x of `s` (b and c excluded) with between(x, b, c) true; Reject("margin") when one of them is
        undecided, Reject("no_fact") when one was not evaluated."""
        true, undecided, missing = self.between_entry(b, c)
        if (undecided and not undecided.isdisjoint(s)) or (missing and not missing.isdisjoint(s)):
            for x in s:  # the first bad member in the set's order names the reason, as a member-wise loop would
                if x != b and x != c:
                    self.holds("between", (x, b, c))
        return s & true

    @property
    def distance_margin(self) -> float:
        return self.tables.th.distance_margin  # type: ignore[union-attr]

    def distances_to(self, anchor: int, objects: list[Any]) -> list[float] | None:
        """Stored distances of `objects` to `anchor` (the ones close/far compare), or None when close/far would
        not come from them (no gravity, an unknown or repeated object, a missing distance): the caller then
        takes the fact-by-fact path."""
        if not self.world or type(anchor) is not int or anchor not in self._pos:
            return None
        d = self.tables.distance_rows()
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

    def centres_to(self, anchor: int, objects: list[Any]) -> tuple[list[float] | None, bool]:
        """Centre distances of `objects` to `anchor` from the nodes' stored centres (None when one lacks a
        centre), and whether one of them stands on the anchor or carries it, or one lies inside the other
        (graph.relations.distances.linked, nested)."""
        nodes = self.tables.nodes
        if nested(self.tables, anchor, *objects):
            return None, True
        ca = nodes[anchor].attributes.get("center")
        out: list[float] | None = [] if ca is not None else None
        tied = False
        for x in objects:
            n = nodes[x]
            tied = tied or linked(n.support, x, nodes[anchor].support, anchor)
            cx = n.attributes.get("center")
            if out is not None and cx is not None and ca is not None:
                out.append(math.dist(cx, ca))
            else:
                out = None
        return out, tied

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
            v = self._has_true_spot = any(f.holds is True for rel in REGION_KINDS for f in self.facts_of(rel))
        return v

    @property
    def largest_between_row(self) -> int:
        """The most objects between any anchor pair (decided true). A `between` step's output is a subset of
        its anchor pair's row, so a step bound to keep more than this rejects every binding."""
        v = self._largest_between_row
        if v is None:
            table = self.tables.table("between") if self.world else None
            v = self._largest_between_row = 0 if table is None else table.largest
        return v

    def region_rounded(self, region: FreeSpaceRegion) -> tuple[tuple[Any, ...], tuple[Any, ...]]:
        """A free-space region's polygon (5 decimals) and world point (6 decimals) as answers record them,
        rounded once per region and sample (callers copy before storing)."""
        hit = self._region_rounded.get(id(region))
        if hit is None or hit[0] is not region:
            poly = tuple((round(float(x), 5), round(float(y), 5)) for x, y in region.polygon_xy)
            hit = self._region_rounded[id(region)] = (
                region,
                poly,
                tuple(round(float(x), 6) for x in region.point_world),
            )
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
