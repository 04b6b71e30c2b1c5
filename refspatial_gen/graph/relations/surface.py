"""Support-surface relations: corner and edge (objects near a surface's corner or along one of its
edges), and free space (answered by regions, see graph/freespace.py).

Why labels depend on the camera: "the far-left corner of the table" is named from the viewer. A corner
or edge whose name would be ambiguous (a table seen diagonally) gets no label and is never asked about.
"""

from __future__ import annotations

from collections.abc import Callable
from typing import TYPE_CHECKING, Any

import numpy as np

from refspatial_gen.core.model import RelationFact
from refspatial_gen.graph.relations.base import SURFACE_SOURCES, Cell, Relation, register
from refspatial_gen.graph.relations.common import FALSE, TRUE, UNDECIDED, cached, pos
from refspatial_gen.graph.scene import SceneGeom, roll_next
from refspatial_gen.graph.support import get_supports, surface_polygon
from refspatial_gen.graph.surface_seen import filter_seen
from refspatial_gen.graph.surface_visible import unseen_why

if TYPE_CHECKING:
    from refspatial_gen.graph.tables import RelationTables

EDGE_AXIS_TOLERANCE = np.deg2rad(30.0)  # an edge's outward normal within this of a viewer axis gets a name
CORNER_SEPARATION = 0.15  # corner coordinates must differ from the centre by this share of the extent


def surface_labels(geom: SceneGeom) -> dict[str, dict[str, Any]]:
    """{surface id: {"polygon": (4,2), "corners": {label: xy}, "edges": {label: (a, b)}}}."""

    def f(g: SceneGeom) -> dict[str, dict[str, Any]]:
        out = {}
        axes = g.camera_axes_horizontal()
        for s in g.surfaces:
            poly = surface_polygon(s.box)
            entry: dict[str, Any] = {"polygon": poly, "corners": {}, "edges": {}, "z": s.top_z}
            out[s.id] = entry
            why = unseen_why(g, s.object_id, poly, s.top_z)
            if why is not None:  # a top a person cannot see is never named (graph/surface_visible.py)
                entry["unseen"] = why
                truth = g.cache.setdefault("truth", {})
                truth[why] = truth.get(why, 0) + 1
                continue
            if axes is None:
                continue
            right, fwd = axes
            c = poly.mean(axis=0)
            lat, dep = (poly - c) @ right[:2], (poly - c) @ fwd[:2]
            ext_l, ext_d = np.ptp(lat), np.ptp(dep)
            ok = (np.abs(lat) > CORNER_SEPARATION * ext_l) & (np.abs(dep) > CORNER_SEPARATION * ext_d)
            names = [("far" if d > 0 else "near") + "-" + ("right" if lt > 0 else "left") for lt, d in zip(lat, dep)]
            if ok.all() and len(set(names)) == 4:
                entry["corners"] = {names[k]: poly[k] for k in range(4)}
            for k in range(4):
                a, b = poly[k], poly[(k + 1) % 4]
                e = b - a
                n = np.array([e[1], -e[0]]) / (np.linalg.norm(e) + 1e-12)  # outward normal of a CCW polygon
                ang = np.arctan2(n @ fwd[:2], n @ right[:2])  # 0 = right, 90 = far, 180 = left, -90 = near
                for label, centre in (
                    ("right edge", 0.0),
                    ("far edge", np.pi / 2),
                    ("left edge", np.pi),
                    ("near edge", -np.pi / 2),
                ):
                    if abs((ang - centre + np.pi) % (2 * np.pi) - np.pi) >= EDGE_AXIS_TOLERANCE:
                        continue
                    if np.ptp(poly @ n) < g.th.edge_depth_factor * g.th.edge_band:
                        # a shallow shelf: every object on it is near both edges along n (audit round 3)
                        truth = g.cache.setdefault("truth", {})
                        truth["edge_shallow_surface"] = truth.get("edge_shallow_surface", 0) + 1
                        continue
                    entry["edges"][label] = (a, b)
            filter_seen(g, entry)  # names only where the camera sees them, at the top face's extent
        return out

    return cached(geom, "surface:labels", f)


def _footprint_to_points(fp: np.ndarray, pts: np.ndarray) -> np.ndarray:
    """Distances from (C, 2) points to a convex footprint (0 inside)."""
    a, b = fp, roll_next(fp, axis=0)
    e = b - a
    rel = pts[:, None, :] - a[None]  # (C, 4, 2)
    t = np.clip(np.sum(rel * e, axis=2) / np.maximum(np.sum(e * e, axis=1), 1e-18), 0, 1)
    d = np.linalg.norm(pts[:, None, :] - (a + t[..., None] * e), axis=2).min(axis=1)
    inside = np.all(e[:, 0] * (pts[:, None, 1] - a[:, 1]) - e[:, 1] * (pts[:, None, 0] - a[:, 0]) >= 0, axis=1)
    return np.where(inside, 0.0, d)


def _band(v: float, low: float, high: float) -> int:
    """`band_matrix` for one value."""
    return FALSE if v > high else (TRUE if v < low else UNDECIDED)


def _footprint_to_edge(fp: np.ndarray, a: np.ndarray, b: np.ndarray) -> float:
    """Smallest distance from the footprint's vertices to the (infinite) edge line, measured inwards."""
    e = (b - a) / (np.linalg.norm(b - a) + 1e-12)
    inward = np.array([-e[1], e[0]])
    return float(max(0.0, ((fp - a) @ inward).min()))


def _corner_edge(geom: SceneGeom) -> dict[tuple[str, int, str, str], tuple[int, float]]:
    """{(rel, object pos, surface id, label): (code, value)} for objects whose support chain ends on a
    surface with labels; False instances omitted."""

    def f(g: SceneGeom) -> dict[tuple[str, int, str, str], tuple[int, float]]:
        th = g.th
        _, roots = get_supports(g)
        labels = surface_labels(g)
        out = {}
        for i in range(g.n):
            sid = roots[i]
            if sid is None or sid not in labels:
                continue
            fp = g.footprints[i]
            corners = sorted(labels[sid]["corners"].items())
            if corners:
                vs = _footprint_to_points(fp, np.array([p for _, p in corners]))
                for (lab, _), v in zip(corners, vs):
                    v = float(v)
                    out[("corner", i, sid, lab)] = (
                        _band(v, th.corner_reach, th.corner_reach + th.surface_band_margin),
                        v,
                    )
            for lab, (a, b) in sorted(labels[sid]["edges"].items()):
                v = _footprint_to_edge(fp, a, b)
                out[("edge", i, sid, lab)] = (_band(v, th.edge_band, th.edge_band + th.surface_band_margin), v)
        return out

    return cached(geom, "surface:corner_edge", f)


def _spot_stored(rel: str) -> Callable[[SceneGeom], list[RelationFact]]:
    """The holding and undecided corner (or edge) instances, by (object id, surface, label)."""

    def stored(geom: SceneGeom) -> list[RelationFact]:
        m = geom.th.surface_band_margin
        items = _corner_edge(geom)
        out = []
        for key in sorted((k for k in items if k[0] == rel), key=lambda k: (int(geom.ids[k[1]]), k[2], k[3])):
            code, v = items[key]
            if code in (TRUE, UNDECIDED):
                out.append(
                    RelationFact(
                        rel, (int(geom.ids[key[1]]), key[2], key[3]), None if code == UNDECIDED else True, v, m
                    )
                )
        return out

    return stored


def _spot_cell(rel: str) -> Callable[[RelationTables, tuple[Any, ...]], Cell | None]:
    """The stored instance; absent = False for an object standing on that surface when the surface has that
    label, else not evaluated."""
    key = "corners" if rel == "corner" else "edges"

    def cell(t: RelationTables, args: tuple[Any, ...]) -> Cell | None:
        f = t.stored(rel, args)
        if f is not None:
            return Cell(f.holds, float(f.value), f.margin)
        a, sid, label = args
        labels = t.surfaces.get(sid, {}).get(key, [])
        if t.th is None or t.nodes[int(a)].attributes.get("surface") != sid or label not in labels:
            return None
        return Cell(False, 0.0, t.th.surface_band_margin)

    return cell


def _spot_domain(rel: str) -> Callable[[RelationTables], list[tuple[Any, ...]]]:
    key = "corners" if rel == "corner" else "edges"
    return lambda t: [(i, sid, lab) for i in t.ids for sid, e in sorted(t.surfaces.items()) for lab in e.get(key, [])]


def _eval(rel: str) -> Callable[..., RelationFact]:
    def evaluate(geom: SceneGeom, a: Any, surface_id: str, label: str) -> RelationFact:
        i = pos(geom, a)
        code, v = _corner_edge(geom).get((rel, i, surface_id, label), (None, 0.0))
        if code is None:
            return RelationFact(rel, (a, surface_id, label), None, 0.0, geom.th.surface_band_margin)
        return RelationFact(
            rel,
            (a, surface_id, label),
            None if code == UNDECIDED else bool(code == TRUE),
            v,
            geom.th.surface_band_margin,
        )

    return evaluate


def _free_eval(geom: SceneGeom, surface_id: str, kind: str, *anchors: Any) -> RelationFact:
    from refspatial_gen.graph.freespace import free_regions

    for r in free_regions(geom):
        if r.surface_id == surface_id and r.kind == kind and tuple(r.anchors) == tuple(anchors):
            return RelationFact("free_space", (surface_id, kind, *anchors), True, r.area, geom.th.free_min_area)
    return RelationFact("free_space", (surface_id, kind, *anchors), False, 0.0, geom.th.free_min_area)


def _free_cell(t: RelationTables, args: tuple[Any, ...]) -> Cell | None:
    if t.th is None:
        return None
    sid, kind, *anchors = args
    for r in t.regions(kind, tuple(anchors)):
        if r.surface_id == sid:
            return Cell(True, float(r.area), t.th.free_min_area)
    return Cell(False, 0.0, t.th.free_min_area)


def _free_instances(t: RelationTables) -> list[RelationFact]:
    """One instance per stored region (regions of one kind and anchors differ by label and area)."""
    if t.th is None:
        return []
    m = t.th.free_min_area
    return [RelationFact("free_space", (r.surface_id, r.kind, *r.anchors), True, r.area, m) for r in t.graph.free_space]


S = ("gravity", "surface")
for _rel, _value, _margin, _definition in (
    (
        "corner",
        "distance from A's footprint to the labelled corner (m)",
        "corner_reach, surface_band_margin",
        "A (or a free point) is within reach of a support surface's corner, named from the viewer (e.g. far-left)",
    ),
    (
        "edge",
        "inward distance from the labelled edge to A's footprint (m)",
        "edge_band, surface_band_margin",
        "A (or a free point) lies within a band along one edge of a support surface (e.g. the right edge); "
        "edges of a surface shallower than edge_depth_factor edge bands along the edge's normal get no name",
    ),
):
    register(
        Relation(
            _rel,
            "surface",
            "world",
            3,
            _value,
            _margin,
            _definition,
            sources=SURFACE_SOURCES,
            storage="sparse",
            needs=S,
            evaluate=_eval(_rel),
            stored=_spot_stored(_rel),
            cell=_spot_cell(_rel),
            domain=_spot_domain(_rel),
        )
    )
register(
    Relation(
        "free_space",
        "surface",
        "world",
        2,
        "visible free area of the region (m^2)",
        "free_min_area, visibility_tolerance",
        "a visible point on a support surface not covered by any object footprint (left/right/front/behind "
        "of, between, corner, edge)",
        sources=SURFACE_SOURCES,
        storage="region",
        needs=S,
        variadic=True,
        evaluate=_free_eval,
        cell=_free_cell,
        instances=_free_instances,
    )
)
