"""Room furniture as static boxes with support surfaces: shelves, cabinets, sofas, beds, counters, tables.

Every piece is axis-aligned, either against a wall (back = +y, left = -x, right = +x; cameras stand on
the -y side) or free-standing, and reserves its floor footprint so pieces never overlap. Each piece
returns the surfaces objects can be placed on, with the free height above them (`max_height`) so
nothing is placed where it would not fit (under the next shelf board).
"""

from __future__ import annotations

import numpy as np
from shapely.geometry import box as shp_box

from refspatial_gen.sources.sim.layout import CLEARANCE, LayoutBuilder, StaticBox, Surface

WALLS = ("back", "left", "right")
GAP = 0.02  # between a piece and its wall


def wall_rect(
    room_half: np.ndarray, wall: str, along: float, width: float, depth: float
) -> tuple[float, float, float, float]:
    """(cx, cy, hx, hy) of a piece `width` wide and `depth` deep against `wall`, at `along` in [-1, 1]."""
    rx, ry = room_half
    if wall == "back":
        span = rx - width / 2 - 0.05
        return float(along * span), float(ry - depth / 2 - GAP), width / 2, depth / 2
    span = ry - width / 2 - 0.05
    sx = -1 if wall == "left" else 1
    return float(sx * (rx - depth / 2 - GAP)), float(along * span), depth / 2, width / 2


def _free(b: LayoutBuilder, floor: Surface, cx: float, cy: float, hx: float, hy: float) -> bool:
    fp = shp_box(cx - hx, cy - hy, cx + hx, cy + hy)
    return floor.rect(0.0).contains(fp) and not any(fp.distance(o) < CLEARANCE for o in floor.fps)


def _reserve(floor: Surface, cx: float, cy: float, hx: float, hy: float, pad: float = 0.02) -> None:
    floor.fps.append(shp_box(cx - hx - pad, cy - hy - pad, cx + hx + pad, cy + hy + pad))


def _box(b: LayoutBuilder, name: str, c, h, look: str) -> None:
    b.statics.append(StaticBox(name, np.asarray(c, float), np.asarray(h, float), look))


def _surface(b: LayoutBuilder, sid: str, kind: str, name: str, cx, cy, hx, hy, z, t=0.02, max_height=10.0) -> Surface:
    s = Surface(sid, kind, name, np.array([cx, cy]), np.array([hx, hy]), float(z), t, max_height)
    b.surfaces.append(s)
    return s


def table(b, floor, sid, name, cx, cy, hx, hy, h, kind="table") -> Surface | None:
    """A four-legged table (dining table, desk, coffee table, side table, nightstand)."""
    if not _free(b, floor, cx, cy, hx, hy):
        return None
    _reserve(floor, cx, cy, hx, hy)
    return b.add_table(sid, kind, name, cx, cy, hx, hy, h, look="table")


def shelf_unit(b: LayoutBuilder, floor: Surface, wall: str, along: float) -> list[Surface]:
    """A bookcase: 3-4 boards between two side panels and a back panel; every board is a surface."""
    rng = b.rng
    width, depth = rng.uniform(0.7, 1.1), rng.uniform(0.28, 0.34)
    n = int(rng.integers(3, 5))
    height = rng.uniform(0.38, 0.45) * n
    cx, cy, hx, hy = wall_rect(floor.half, wall, along, width, depth)
    if not _free(b, floor, cx, cy, hx, hy):
        return []
    _reserve(floor, cx, cy, hx, hy)
    back = {"back": (0, 1), "left": (-1, 0), "right": (1, 0)}[wall]
    side_axis = 0 if wall == "back" else 1
    t = 0.018
    if side_axis == 0:
        _box(b, "shelf_back", [cx, cy + back[1] * (hy - 0.005), height / 2], [hx, 0.005, height / 2], "shelf")
    else:
        _box(b, "shelf_back", [cx + back[0] * (hx - 0.005), cy, height / 2], [0.005, hy, height / 2], "shelf")
    for sgn in (-1, 1):
        c = [cx + sgn * (hx - t / 2), cy, height / 2] if side_axis == 0 else [cx, cy + sgn * (hy - t / 2), height / 2]
        h = [t / 2, hy, height / 2] if side_axis == 0 else [hx, t / 2, height / 2]
        _box(b, f"shelf_side{sgn:+d}", c, h, "shelf")
    ix, iy = (hx - t, hy - 0.012) if side_axis == 0 else (hx - 0.012, hy - t)
    gap = height / n
    names = {
        3: ["the bottom shelf", "the middle shelf", "the top shelf"],
        4: ["the bottom shelf", "the second shelf", "the third shelf", "the top shelf"],
    }[n]
    out = []
    for i in range(n):
        z = 0.06 + i * gap
        _box(b, f"shelf_board{i}", [cx, cy, z - t / 2], [ix, iy, t / 2], "shelf")
        top = i == n - 1
        s = _surface(b, f"shelf{i}", "shelf", names[i], cx, cy, ix, iy, z, t, 0.5 if top else gap - t - 0.02)
        out.append(s)
    return out


def cabinet(b: LayoutBuilder, floor: Surface, wall: str, along: float) -> list[Surface]:
    """A closed low cabinet (or chest of drawers) whose top holds things."""
    rng = b.rng
    width, depth, h = rng.uniform(0.6, 1.2), rng.uniform(0.4, 0.5), rng.uniform(0.7, 0.95)
    cx, cy, hx, hy = wall_rect(floor.half, wall, along, width, depth)
    if not _free(b, floor, cx, cy, hx, hy):
        return []
    _reserve(floor, cx, cy, hx, hy)
    _box(b, "cabinet_body", [cx, cy, (h - 0.03) / 2], [hx - 0.01, hy - 0.01, (h - 0.03) / 2], "cabinet")
    _box(b, "cabinet_top", [cx, cy, h - 0.015], [hx, hy, 0.015], "table")
    return [_surface(b, "cabinet", "cabinet", "the cabinet", cx, cy, hx, hy, h, 0.03)]


def counter(b: LayoutBuilder, floor: Surface, along: float) -> list[Surface]:
    """A kitchen counter along the back wall, with a wall shelf above it (a second, higher surface)."""
    rng = b.rng
    width, depth, h = rng.uniform(1.2, 2.0), 0.6, rng.uniform(0.88, 0.94)
    cx, cy, hx, hy = wall_rect(floor.half, "back", along, width, depth)
    if not _free(b, floor, cx, cy, hx, hy):
        return []
    _reserve(floor, cx, cy, hx, hy)
    _box(b, "counter_body", [cx, cy, (h - 0.04) / 2], [hx - 0.02, hy - 0.02, (h - 0.04) / 2], "cabinet")
    _box(b, "counter_top", [cx, cy, h - 0.02], [hx, hy, 0.02], "counter")
    out = [_surface(b, "counter", "counter", "the counter", cx, cy, hx, hy, h, 0.04)]
    if rng.random() < 0.75:
        zs, sd, sw = h + rng.uniform(0.42, 0.55), 0.24, min(hx, rng.uniform(0.4, 0.7))
        sy = floor.half[1] - sd / 2 - GAP
        _box(b, "wall_shelf", [cx, sy, zs - 0.01], [sw, sd / 2, 0.01], "shelf")
        out.append(_surface(b, "wall_shelf", "shelf", "the wall shelf", cx, sy, sw, sd / 2, zs, 0.02, 0.4))
    return out


def sofa(b: LayoutBuilder, floor: Surface, along: float) -> list[Surface]:
    """A sofa against the back wall facing the room: its seat between the arms is a surface."""
    rng = b.rng
    width, depth, seat = rng.uniform(1.6, 2.2), rng.uniform(0.8, 0.95), rng.uniform(0.42, 0.47)
    cx, cy, hx, hy = wall_rect(floor.half, "back", along, width, depth)
    if not _free(b, floor, cx, cy, hx, hy):
        return []
    _reserve(floor, cx, cy, hx, hy)
    arm, back = 0.16, 0.22
    _box(b, "sofa_base", [cx, cy, seat / 2], [hx, hy, seat / 2], "sofa")
    _box(b, "sofa_back", [cx, cy + hy - back / 2, 0.425], [hx, back / 2, 0.425], "sofa")
    for sgn in (-1, 1):
        _box(
            b,
            f"sofa_arm{sgn:+d}",
            [cx + sgn * (hx - arm / 2), cy - back / 2, seat + 0.09],
            [arm / 2, hy - back / 2, 0.09],
            "sofa",
        )
    sx, sy = hx - arm - 0.01, (depth - back) / 2 - 0.01
    return [_surface(b, "sofa", "sofa", "the sofa", cx, cy - back / 2, sx, sy, seat, 0.1)]


def bed(b: LayoutBuilder, floor: Surface, along: float) -> list[Surface]:
    """A bed with its head against the back wall: the mattress top is a surface."""
    rng = b.rng
    width, length, top = rng.uniform(1.0, 1.6), rng.uniform(1.9, 2.1), rng.uniform(0.5, 0.6)
    cx, cy, hx, hy = wall_rect(floor.half, "back", along, width, length)
    if not _free(b, floor, cx, cy, hx, hy):
        return []
    _reserve(floor, cx, cy, hx, hy)
    _box(b, "bed_frame", [cx, cy, 0.15], [hx, hy, 0.15], "table")
    _box(b, "bed_mattress", [cx, cy, (0.3 + top) / 2], [hx - 0.02, hy - 0.02, (top - 0.3) / 2], "bedding")
    _box(b, "bed_head", [cx, cy + hy - 0.03, 0.55], [hx, 0.03, 0.55], "table")
    s = _surface(b, "bed", "bed", "the bed", cx, cy - 0.1, hx - 0.06, hy - 0.25, top, 0.2)
    # the mattress top a person sees, from its foot to the headboard (audit round 4: a "far-right corner" taken
    # 0.3 m short of the headboard, where only the placement area ended)
    s.face = (cx, cy - 0.02, hx - 0.02, hy - 0.04)
    return [s]


def wall_table(
    b: LayoutBuilder,
    floor: Surface,
    wall: str,
    along: float,
    width: float,
    depth: float,
    h: float,
    sid: str,
    name: str,
    kind: str,
) -> list[Surface]:
    """A table against a wall (desk, nightstand, side table)."""
    cx, cy, hx, hy = wall_rect(floor.half, wall, along, width, depth)
    s = table(b, floor, sid, name, cx, cy, hx, hy, h, kind)
    return [s] if s is not None else []
