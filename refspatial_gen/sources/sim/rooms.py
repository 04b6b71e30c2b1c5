"""Layout kinds: a tabletop in a furnished room, and rooms of furniture with several support surfaces.

RefSpatial's simulated scenes put 3-9 objects on a tabletop inside a furnished room; here a `room`
scene has a themed group of furniture (living room, bedroom, kitchen, office) whose 2-3 focus surfaces
at different heights (sofa seat, coffee table, bed, nightstand, counter, wall shelf, desk, shelf boards,
cabinet top) get 3-9 objects each, and the other surfaces a few. Cameras aim at the focus group.
"""

from __future__ import annotations

from collections.abc import Callable
from typing import Any

import numpy as np
from shapely import affinity

from refspatial_gen.assets import Catalog
from refspatial_gen.sources.sim import furniture as F
from refspatial_gen.sources.sim.layout import (
    CLEARANCE,
    DROP_GAP,
    LayoutBuilder,
    SceneDesc,
    Surface,
    appearance,
    footprint,
)

Theme = Callable[[LayoutBuilder, Surface], tuple[list[Surface], list[Surface], Surface | None]]


def _n(rng: np.random.Generator, cfg: dict[str, Any], surf: Surface) -> int:
    """Objects for a focus surface: `objects_per_surface` (3-9), at most one per ~180 cm^2 of it."""
    lo, hi = (int(x) for x in cfg.get("objects_per_surface", [3, 9]))
    cap = max(1, int(4 * surf.half[0] * surf.half[1] / 0.018))
    return min(int(rng.integers(lo, hi + 1)), cap)


def _side(rng) -> str:
    return "left" if rng.random() < 0.5 else "right"


def _try(
    piece, b: LayoutBuilder, floor: Surface, wall: str, lo: float = -0.9, hi: float = 0.9, tries: int = 6
) -> list[Surface]:
    """A wall piece at the first free position along the wall (furniture never overlaps)."""
    for _ in range(tries):
        out = piece(b, floor, wall, float(b.rng.uniform(lo, hi)))
        if out:
            return out
    return []


def living(b: LayoutBuilder, floor: Surface):
    rng = b.rng
    seat = F.sofa(b, floor, rng.uniform(-0.3, 0.3))
    focus, other = list(seat), []
    if seat:
        s = seat[0]
        ct = F.table(
            b,
            floor,
            "coffee_table",
            "the coffee table",
            s.center[0] + rng.normal(0, 0.1),
            s.center[1] - s.half[1] - 0.75,
            rng.uniform(0.4, 0.6),
            rng.uniform(0.25, 0.33),
            rng.uniform(0.4, 0.46),
            "table",
        )
        focus += [ct] if ct else []
        sx = s.center[0] + (1 if rng.random() < 0.5 else -1) * (s.half[0] + 0.5)
        st = F.table(
            b,
            floor,
            "side_table",
            "the side table",
            sx,
            floor.half[1] - 0.3,
            0.22,
            0.22,
            rng.uniform(0.5, 0.62),
            "table",
        )
        focus += [st] if st else []
    other += _try(F.shelf_unit, b, floor, _side(rng), 0.0, 0.9)
    return focus, other, None


def bedroom(b: LayoutBuilder, floor: Surface):
    rng = b.rng
    bed = F.bed(b, floor, rng.uniform(-0.3, 0.3))
    focus, other = list(bed), []
    if bed:
        s = bed[0]
        sgn = 1 if rng.random() < 0.5 else -1
        ns = F.table(
            b,
            floor,
            "nightstand",
            "the nightstand",
            s.center[0] + sgn * (s.half[0] + 0.34),
            floor.half[1] - 0.26,
            0.22,
            0.2,
            rng.uniform(0.52, 0.62),
            "nightstand",
        )
        focus += [ns] if ns else []
    cab = _try(F.cabinet, b, floor, _side(rng), -0.2, 0.9)
    focus += cab if len(focus) < 2 else []
    other += [] if len(focus) < 2 and cab else cab
    if rng.random() < 0.5:
        other += _try(F.shelf_unit, b, floor, "left" if cab and cab[0].center[0] > 0 else "right")
    return focus, other, None


def kitchen(b: LayoutBuilder, floor: Surface):
    rng = b.rng
    focus = F.counter(b, floor, rng.uniform(-0.5, 0.5))
    t = F.table(
        b,
        floor,
        "table",
        "the table",
        rng.uniform(-0.4, 0.4),
        rng.uniform(-0.5, 0.0),
        rng.uniform(0.45, 0.7),
        rng.uniform(0.35, 0.45),
        rng.uniform(0.72, 0.78),
    )
    focus += [t] if t else []
    other = _try(F.shelf_unit, b, floor, _side(rng)) if rng.random() < 0.5 else []
    return focus, other, t


def office(b: LayoutBuilder, floor: Surface):
    rng = b.rng
    along = rng.uniform(-0.5, 0.1)
    focus = F.wall_table(
        b,
        floor,
        "back",
        along,
        rng.uniform(1.1, 1.5),
        rng.uniform(0.6, 0.75),
        rng.uniform(0.72, 0.76),
        "desk",
        "the desk",
        "desk",
    )
    shelves = _try(F.shelf_unit, b, floor, "back") or _try(F.shelf_unit, b, floor, _side(rng), 0.0, 0.9)
    focus += shelves[:2]
    other = shelves[2:] + _try(F.cabinet, b, floor, _side(rng))
    return focus, other, (focus[0] if focus else None)


THEMES: dict[str, Theme] = {"living": living, "bedroom": bedroom, "kitchen": kitchen, "office": office}


def _chairs(b: LayoutBuilder, floor: Surface, t: Surface, k: int) -> None:
    """Chairs facing a table (some turned away a little), never through furniture."""
    rng, cat = b.rng, b.cat.categories.get("chair")
    if cat is None:
        return
    for side in rng.permutation(4)[:k]:
        geo, color, rgb, acc, mat = b.make(cat)
        d = np.array([[1, 0], [-1, 0], [0, 1], [0, -1]][side], float)
        off = (t.half[0] if side < 2 else t.half[1]) + 0.27 + rng.uniform(0.0, 0.2)
        xy = (
            t.center
            + d * off
            + (np.array([0, rng.uniform(-0.2, 0.2)]) if side < 2 else np.array([rng.uniform(-0.3, 0.3), 0]))
        )
        yaw = float(np.arctan2(-d[1], -d[0]) + rng.normal(0, 0.15))
        fp = affinity.translate(footprint(geo, yaw), xy[0], xy[1])
        if not floor.rect(0.05).contains(fp) or any(fp.distance(o) < CLEARANCE for o in floor.fps):
            continue
        floor.fps.append(fp)
        b._add(
            cat, geo, color, rgb, acc, mat, np.array([xy[0], xy[1], -geo.bounds()[0][2] + DROP_GAP]), yaw, "floor", fp
        )


def room_layout(catalog: Catalog, rng: np.random.Generator, cfg: dict[str, Any]) -> SceneDesc:
    """A themed room: furniture group, 3-9 objects on each focus surface, a few elsewhere, some on the floor."""
    b = LayoutBuilder(catalog, rng, cfg)
    rx, ry = rng.uniform(2.2, 3.0), rng.uniform(2.0, 2.8)
    floor = Surface("floor", "floor", "the floor", np.zeros(2), np.array([rx, ry]), 0.0, 0.0)
    b.surfaces.append(floor)
    names = sorted(cfg.get("room_themes") or THEMES)
    theme = names[int(rng.integers(len(names)))]
    focus, other, dining = THEMES[theme](b, floor)
    if dining is not None:
        _chairs(b, floor, dining, int(rng.integers(1, 3 if theme == "office" else 4)))
    cap = int(cfg.get("max_objects", 24))
    for s in focus:
        b.fill([s], min(_n(rng, cfg, s), cap - len(b.objects)))
    for s in other:
        b.fill([s], min(int(rng.integers(0, 3)), cap - len(b.objects)))
    for _ in range(int(rng.integers(0, 3))):
        if len(b.objects) < cap:
            b.place_on_surface(floor, b.pick_category("room"), tries=20)
    ids = [s.id for s in focus] or [s.id for s in other] or ["floor"]
    return SceneDesc("room", b.objects, b.statics, b.surfaces, ids, np.array([rx, ry]), True, appearance(rng))


def tabletop_layout(catalog: Catalog, rng: np.random.Generator, cfg: dict[str, Any]) -> SceneDesc:
    """One table with 3-9 objects (RefSpatial's tabletop) in a room with a piece or two of furniture behind."""
    b = LayoutBuilder(catalog, rng, cfg)
    rx, ry = rng.uniform(2.0, 3.0), rng.uniform(2.0, 3.0)
    floor = Surface("floor", "floor", "the floor", np.zeros(2), np.array([rx, ry]), 0.0, 0.0)
    hx, hy, h = rng.uniform(0.4, 0.8), rng.uniform(0.3, 0.5), rng.uniform(0.72, 0.78)
    table = F.table(b, floor, "table", "the table", 0.0, 0.0, hx, hy, h)
    lo, hi = sorted((int(cfg.get("min_objects", 3)), int(cfg.get("max_objects", 24))))
    n = int(np.clip(_n(rng, cfg, table), lo, hi))
    b.fill([table], n)
    for piece in (F.cabinet, F.shelf_unit)[: int(rng.integers(0, 3))]:
        for s in _try(piece, b, floor, ("back", "left", "right")[int(rng.integers(3))]):
            b.fill([s], int(rng.integers(0, 2)))
    return SceneDesc("tabletop", b.objects, b.statics, b.surfaces, ["table"], np.array([rx, ry]), True, appearance(rng))


LAYOUTS = {"tabletop": tabletop_layout, "room": room_layout}
