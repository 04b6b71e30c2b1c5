"""Orientation: camera rotations to face an object, angles between fronts, facing / facing away, and
directions in an anchor's own frame ("left of the laptop from the laptop's point of view").

Why horizontal fronts: a front direction is about where an object "looks" on the ground plane; a front
that points up or down (|z| > 0.7) has no horizontal meaning and leaves these relations undecided.
"""

from __future__ import annotations

from collections.abc import Callable
from typing import TYPE_CHECKING, Any

import numpy as np

from refspatial_gen.core.model import RelationFact
from refspatial_gen.graph.relations.base import FRONT_SOURCES, T_FALSE, T_UNDECIDED, Cell, Relation, register
from refspatial_gen.graph.relations.common import FALSE, TRUE, UNDECIDED, Matrices, cached, fact, holds_of, pos
from refspatial_gen.graph.relations.lookup import sparse_cell, sparse_table, stored_cell
from refspatial_gen.graph.scene import SceneGeom, roll_next

if TYPE_CHECKING:
    from refspatial_gen.graph.tables import RelationTables

MAX_FRONT_Z = 0.7
SECTORS = ("obj_front", "obj_left", "obj_behind", "obj_right")  # centred on 0, 90, 180, -90 degrees


def horizontal_fronts(geom: SceneGeom) -> np.ndarray:
    """(n, 2) unit horizontal fronts (NaN where unknown or too vertical)."""
    f = geom.fronts.copy()
    bad = ~geom.has_front | (np.abs(f[:, 2]) > MAX_FRONT_Z)
    h = f[:, :2]
    nrm = np.linalg.norm(h, axis=1, keepdims=True)
    with np.errstate(invalid="ignore", divide="ignore"):
        h = h / nrm
    h[bad] = np.nan
    return h


# ------------------------------------------------------------------ camera rotations (unary)
def _rotation_h(geom: SceneGeom, i: int) -> RelationFact:
    x, _, z = geom.cam_centers[i]
    v = float(np.arctan2(x, z))
    m = geom.th.rotation_margin
    return RelationFact("rotation_horizontal", (int(geom.ids[i]),), True if abs(v) > m and z > 0 else None, v, m)


def view_tilt(cam_point: Any) -> float:
    """Tilt (rad, + = up) the camera must make about its own right axis, after its horizontal turn
    (`atan2(x, z)`), to put a camera-frame point on its optical axis: the point's elevation above the
    plane of the camera's optical and right axes. View-relative: 0 for a point on the optical axis
    however the camera is pitched (OpenCV camera frame, y down)."""
    x, y, z = (float(c) for c in cam_point)
    return float(np.arctan2(-y, np.hypot(x, z)))


def _rotation_v(geom: SceneGeom, i: int) -> RelationFact:
    """The tilt from the current view (`view_tilt`); undecided inside the margin or behind the camera."""
    m = geom.th.rotation_margin
    v = view_tilt(geom.cam_centers[i])
    ok = abs(v) > m and geom.cam_centers[i][2] > 0
    return RelationFact("rotation_vertical", (int(geom.ids[i]),), True if ok else None, v, m)


# ------------------------------------------------------------------ angle between fronts (symmetric)
def angle_between(h1: Any, h2: Any) -> float | None:
    """Angle (rad) between two horizontal unit fronts, None when either is unknown."""
    h1, h2 = np.asarray(h1, float), np.asarray(h2, float)
    if not (np.isfinite(h1).all() and np.isfinite(h2).all()):
        return None
    return float(np.arccos(np.clip(h1 @ h2, -1.0, 1.0)))


def _angle(geom: SceneGeom, i: int, j: int) -> RelationFact:
    h = horizontal_fronts(geom)
    m = geom.th.angle_margin
    v = angle_between(h[i], h[j])
    return RelationFact("angle", (int(geom.ids[i]), int(geom.ids[j])), None if v is None else True, v or 0.0, m)


# ------------------------------------------------------------------ facing / facing away (ordered)
def rays_hit_polygons(origins: np.ndarray, dirs: np.ndarray, polys: np.ndarray, pad: float) -> np.ndarray:
    """(n, m): does the 2D ray origins[i] + t dirs[i] (t > 0) meet convex CCW polygon j grown by `pad`?"""
    a = polys
    e = roll_next(polys, axis=1) - polys
    nrm = np.stack([e[..., 1], -e[..., 0]], axis=-1) / (np.linalg.norm(e, axis=-1, keepdims=True) + 1e-12)  # outward
    num = np.einsum("mkd,mkd->mk", a, nrm)[None, :, :] - np.einsum("id,mkd->imk", origins, nrm) + pad  # (n,m,k)
    den = np.einsum("id,mkd->imk", dirs, nrm)
    with np.errstate(divide="ignore", invalid="ignore"):
        t = num / den
    par = np.abs(den) < 1e-12
    tmax = np.where(den > 1e-12, t, np.inf).min(axis=2)
    tmin = np.maximum(np.where(den < -1e-12, t, -np.inf).max(axis=2), 1e-9)
    blocked = np.any(par & (num < 0), axis=2)
    return (tmin <= tmax) & ~blocked


def _facing_matrix(geom: SceneGeom, sign: float) -> Matrices:
    def f(g: SceneGeom) -> Matrices:
        n = g.n
        h = horizontal_fronts(g) * sign
        th = g.th
        ok = np.asarray(np.isfinite(h).all(axis=1))
        hh = np.where(ok[:, None], h, 0.0)
        d = g.centers[None, :, :2] - g.centers[:, None, :2]  # (i, j): from i to j
        dist = np.linalg.norm(d, axis=2)
        cosang = np.einsum("ijd,id->ij", d, hh) / np.maximum(dist, 1e-9)
        v = np.arccos(np.clip(cosang, -1, 1))
        hit_in = rays_hit_polygons(g.centers[:, :2], hh, g.footprints, -0.005)
        hit_out = rays_hit_polygons(g.centers[:, :2], hh, g.footprints, 0.02)
        codes = np.full((n, n), UNDECIDED, dtype=np.int8)
        codes[(v > th.facing_cone + th.facing_margin) & ~hit_out] = FALSE
        codes[(v < th.facing_cone - th.facing_margin) | hit_in] = TRUE
        codes[g.surface_distance <= 1e-6] = UNDECIDED  # overlapping boxes: no direction between them
        codes[~ok, :] = UNDECIDED
        np.fill_diagonal(codes, UNDECIDED)
        v[~ok, :] = np.pi
        return v, codes, th.facing_margin

    return cached(geom, f"orient:facing{sign:+.0f}", f)


# ------------------------------------------------------------------ object-frame directions
def bearings(centers_xy: np.ndarray, fronts_h: np.ndarray) -> np.ndarray:
    """theta[i, j]: bearing of i's centre in j's own frame (0 = j's front, +pi/2 = j's left); NaN
    where j has no horizontal front."""
    left = np.stack([-fronts_h[:, 1], fronts_h[:, 0]], axis=1)  # up x front
    d = centers_xy[:, None, :] - centers_xy[None, :, :]  # (i, j): from j to i
    return np.arctan2(np.einsum("ijd,jd->ij", d, left), np.einsum("ijd,jd->ij", d, fronts_h))


def sector_codes(theta: Any, margin: float, outside: Any) -> dict[str, np.ndarray]:
    """Decisions (int8 arrays shaped like theta) for each of the four 90-degree sectors. `outside` is
    False where A overlaps the anchor (no direction)."""
    theta = np.asarray(theta, float)
    out = {}
    for k, rel in enumerate(SECTORS):
        c = (k * np.pi / 2 + np.pi) % (2 * np.pi) - np.pi
        off = np.abs((theta - c + np.pi) % (2 * np.pi) - np.pi)  # 0..pi from the sector's centre
        codes = np.full(theta.shape, UNDECIDED, dtype=np.int8)
        codes[off < np.pi / 4 - margin] = TRUE
        codes[off > np.pi / 4 + margin] = FALSE
        codes[~np.asarray(outside, bool) | ~np.isfinite(theta)] = UNDECIDED
        out[rel] = codes
    return out


def _sector_matrix(geom: SceneGeom) -> np.ndarray:
    return cached(geom, "orient:sector", lambda g: bearings(g.centers[:, :2], horizontal_fronts(g)))


def _sector_fact(geom: SceneGeom, i: int, j: int, rel: str) -> RelationFact:
    theta = _sector_matrix(geom)[i, j]
    m = geom.th.sector_margin
    args = (int(geom.ids[i]), int(geom.ids[j]))
    if i == j or not np.isfinite(theta):
        return RelationFact(rel, args, None, 0.0, m)
    outside = geom.surface_distance[i, j] > 1e-6
    return fact(rel, args, int(sector_codes(theta, m, outside)[rel]), theta, m)


# ------------------------------------------------------------------ stored instances
def _ordered_ids(geom: SceneGeom) -> list[int]:
    return [int(i) for i in np.argsort(geom.ids, kind="stable")]


def _rotation_stored(fn: Callable[[SceneGeom, int], RelationFact]) -> Callable[[SceneGeom], list[RelationFact]]:
    return lambda geom: [fn(geom, i) for i in _ordered_ids(geom)]


def _facing_stored(rel: str, sign: float) -> Callable[[SceneGeom], list[RelationFact]]:
    def stored(geom: SceneGeom) -> list[RelationFact]:
        order = _ordered_ids(geom)
        fr = [i for i in order if np.isfinite(horizontal_fronts(geom)[i]).all()]
        v, codes, m = _facing_matrix(geom, sign)
        return [
            fact(rel, (int(geom.ids[i]), int(geom.ids[j])), codes[i, j], v[i, j], m)
            for i in fr
            for j in order
            if i != j and codes[i, j] != FALSE
        ]

    return stored


def _unary_eval(fn: Callable[[SceneGeom, int], RelationFact]) -> Callable[..., RelationFact]:
    return lambda geom, a: fn(geom, pos(geom, a))


def _angle_eval(geom: SceneGeom, a: Any, b: Any) -> RelationFact:
    f = _angle(geom, pos(geom, a), pos(geom, b))
    return RelationFact("angle", (a, b), f.holds, f.value, f.margin)


def _facing_eval(sign: float, rel: str) -> Callable[..., RelationFact]:
    def evaluate(geom: SceneGeom, a: Any, b: Any) -> RelationFact:
        i, j = pos(geom, a), pos(geom, b)
        v, codes, m = _facing_matrix(geom, sign)
        return fact(rel, (a, b), codes[i, j], v[i, j], m)

    return evaluate


def _sector_eval(rel: str) -> Callable[..., RelationFact]:
    return lambda geom, a, b: _sector_fact(geom, pos(geom, a), pos(geom, b), rel)


# ------------------------------------------------------------------ lookups on a stored graph
def _front(t: RelationTables, a: Any) -> Any:
    return t.nodes[int(a)].attributes.get("front")


def _facing_absent(t: RelationTables, args: tuple[Any, ...]) -> Cell | None:
    """An absent facing instance is False, or undecided when A has no (horizontal) front."""
    if t.th is None:
        return None
    return Cell(None if _front(t, args[0]) is None else False, float(np.pi), t.th.facing_margin)


def _facing_row(t: RelationTables, a: int) -> int:
    return T_UNDECIDED if _front(t, a) is None else T_FALSE


def _angle_cell(t: RelationTables, args: tuple[Any, ...]) -> Cell | None:
    if t.th is None:
        return None
    fa, fb = (_front(t, x) for x in args)
    v = None if fa is None or fb is None else angle_between(fa, fb)
    return Cell(None if v is None else True, v or 0.0, t.th.angle_margin)


def _sector_cell(rel: str) -> Callable[[RelationTables, tuple[Any, ...]], Cell | None]:
    def cell(t: RelationTables, args: tuple[Any, ...]) -> Cell | None:
        if t.th is None:
            return None
        a, b = args
        m = t.th.sector_margin
        fb = _front(t, b)
        if fb is None:
            return Cell(None, 0.0, m)
        ca = np.array(t.nodes[int(a)].attributes["center"][:2], float)
        cb = np.array(t.nodes[int(b)].attributes["center"][:2], float)
        theta = bearings(np.stack([ca, cb]), np.array([[np.nan, np.nan], fb], float))[0, 1]
        d = t.distance(a, b)
        code = sector_codes(np.array(theta), m, np.array(d is not None and d > 1e-6))[rel]
        return Cell(holds_of(int(code)), float(theta), m)

    return cell


F = ("gravity", "front")
register(
    Relation(
        "rotation_horizontal",
        "orientation",
        "cam",
        1,
        "atan2(x, z) of A's centre in the camera frame (rad, + = right)",
        "rotation_margin",
        "angle the camera must yaw to face the object",
        storage="unary",
        evaluate=_unary_eval(_rotation_h),
        stored=_rotation_stored(_rotation_h),
        cell=stored_cell("rotation_horizontal"),
    )
)
register(
    Relation(
        "rotation_vertical",
        "orientation",
        "cam",
        1,
        "tilt of the camera from its current view, after its horizontal turn, to face A's centre (rad, + = up)",
        "rotation_margin",
        "angle the camera must tilt about its own right axis to face the object (view-relative)",
        storage="unary",
        evaluate=_unary_eval(_rotation_v),
        stored=_rotation_stored(_rotation_v),
        cell=stored_cell("rotation_vertical"),
    )
)
register(
    Relation(
        "angle",
        "orientation",
        "world",
        2,
        "angle between the horizontal front directions (rad)",
        "angle_margin",
        "angle between two objects' front directions",
        sources=FRONT_SOURCES,
        storage="derived",
        needs=F,
        evaluate=_angle_eval,
        cell=_angle_cell,
    )
)
for _rel, _sign, _what in (
    ("facing", 1.0, "B lies within a 30-degree cone around A's front direction, or A's front ray hits B's footprint"),
    ("facing_away", -1.0, "same test as facing with A's back direction: A turns its back to B"),
):
    register(
        Relation(
            _rel,
            "orientation",
            "obj",
            2,
            f"angle between A's {'front' if _sign > 0 else 'back'} and the direction to B (rad)",
            "facing_cone, facing_margin",
            _what,
            sources=FRONT_SOURCES,
            storage="sparse",
            needs=F,
            qa="pairwise",
            key_step="Orientation",
            evaluate=_facing_eval(_sign, _rel),
            stored=_facing_stored(_rel, _sign),
            cell=sparse_cell(_rel, _facing_absent),
            table=sparse_table(_rel, _facing_row),
        )
    )
for _rel, _what in (
    ("obj_front", "in front of"),
    ("obj_left", "to the left of"),
    ("obj_behind", "behind"),
    ("obj_right", "to the right of"),
):
    register(
        Relation(
            _rel,
            "object_frame",
            "obj",
            2,
            "bearing of A's centre in B's own frame (rad, 0 = B's front, + = B's left)",
            "sector_margin",
            f"A is {_what} B from B's own point of view (90-degree sector around B's front axes)",
            sources=FRONT_SOURCES,
            storage="derived",
            needs=F,
            spec=False,
            evaluate=_sector_eval(_rel),
            cell=_sector_cell(_rel),
        )
    )
