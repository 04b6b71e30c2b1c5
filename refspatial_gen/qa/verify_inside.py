"""The verifier's own "inside": a share of A's box in B's box, and the receptacle rule, from the stored boxes.

Why its own code: the generator decides inside on an 8x8x8 lattice of A's box and the receptacle rule on the
footprints its scene geometry fits (graph/relations/containment.py, graph/relations/receptacle.py); this
recomputes one pair on a 7x7x7 lattice, with the footprint as the convex hull of the gravity-aligned box's
corners and the sizes from the box's own axes, sharing no code with it but the receptacle table
(truth/containers.py: the data, like verify_truth's size ranges). A person says "in" only for a receptacle
that A fits in and lies over (audit round 4: "the bin in the desk" stood on the floor at the desk's end).
"""

from __future__ import annotations

from typing import TYPE_CHECKING, Any

import numpy as np

from refspatial_gen.truth.containers import can_contain

if TYPE_CHECKING:
    from refspatial_gen.qa.verify_world import World

LATTICE = 7
SHARE_TOL = 0.03  # the two lattices' shares of one pair differ by less than this; the band is 0.10 wide
PAD_M = 0.01  # m: footprint and bottom tolerance (the graph fits rectangles; this takes the hull)
SIZE_TOL = 0.02  # relative: extents compared with the overhang limit


def _lattice(box: Any, n: int) -> np.ndarray:
    u = (np.arange(n) + 0.5) / n - 0.5
    g = np.stack(np.meshgrid(u, u, u, indexing="ij"), axis=-1).reshape(-1, 3) * np.asarray(box.size, float)
    out: np.ndarray = g @ np.asarray(box.rotation, float).T + np.asarray(box.center, float)
    return out


def share_inside(a: Any, b: Any, n: int = LATTICE) -> float:
    """Share of box a's volume inside box b (cell centres of an n^3 lattice)."""
    local = (_lattice(a, n) - np.asarray(b.center, float)) @ np.asarray(b.rotation, float)
    return float(np.all(np.abs(local) <= np.asarray(b.size, float) / 2 + 1e-9, axis=1).mean())


def _hull(xy: np.ndarray) -> np.ndarray:
    """Convex hull (counter-clockwise) of 2D points, monotone chain."""
    pts = sorted(set(map(tuple, np.round(xy, 9))))
    if len(pts) < 3:
        return np.array(pts)

    def half(seq: list[tuple[float, ...]]) -> list[tuple[float, ...]]:
        out: list[tuple[float, ...]] = []
        for p in seq:
            while (
                len(out) >= 2
                and ((out[-1][0] - out[-2][0]) * (p[1] - out[-2][1]) - (out[-1][1] - out[-2][1]) * (p[0] - out[-2][0]))
                <= 0
            ):
                out.pop()
            out.append(p)
        return out

    lower, upper = half(pts), half(pts[::-1])
    return np.array(lower[:-1] + upper[:-1])


def _in_hull(p: np.ndarray, hull: np.ndarray, pad: float) -> bool:
    if len(hull) < 3:
        return False
    e = np.roll(hull, -1, axis=0) - hull
    cross = (e[:, 0] * (p[1] - hull[:, 1]) - e[:, 1] * (p[0] - hull[:, 0])) / (np.linalg.norm(e, axis=1) + 1e-12)
    return bool(np.all(cross >= -pad))


def _shape(box: Any, G: np.ndarray) -> tuple[np.ndarray, tuple[float, float, float], float, float]:
    """(corners in the gravity frame, (long side, short side, height), bottom z, volume)."""
    R = G @ np.asarray(box.rotation, float)
    size = np.asarray(box.size, float)
    up = int(np.argmax(np.abs(R[2])))  # the box axis nearest the vertical
    flat = sorted((float(size[k]) for k in range(3) if k != up), reverse=True)
    signs = np.array([[x, y, z] for x in (-1, 1) for y in (-1, 1) for z in (-1, 1)], float)
    corners = (signs * size / 2) @ R.T + G @ np.asarray(box.center, float)
    height = float(corners[:, 2].max() - corners[:, 2].min())
    return corners, (flat[0], flat[1], height), float(corners[:, 2].min()), float(np.prod(size))


def receptacle_ok(w: World, a: int, b: int) -> bool:
    """B can hold A, A fits in it (overhang limit, smaller volume) and lies over its floor."""
    G, th = w.geom.gravity.rotation, w.geom.th
    oa, ob = w.objects[a], w.objects[b]
    ca, sa, bot_a, va = _shape(oa.box, G)
    cb, sb, bot_b, vb = _shape(ob.box, G)
    if not can_contain(ob.category, oa.category, sb, sa):
        return False
    if sa[0] > th.inside_max_overhang * sb[0] * (1 + SIZE_TOL) or va >= vb:
        return False
    centre = ca[:, :2].mean(axis=0)
    return _in_hull(centre, _hull(cb[:, :2]), PAD_M) and bot_a >= bot_b - th.stack_tolerance - PAD_M


def inside_holds(w: World, a: int, b: int) -> bool | None:
    """inside(a, b) as a question may ask it: False when little of A's box is in B's, None (undecided) in
    the band or when B is no receptacle A fits in and lies over, True otherwise. Each side of the band is
    widened by SHARE_TOL (the lattices differ), so a decision the generator could make is accepted."""
    th = w.geom.th
    share = share_inside(w.objects[a].box, w.objects[b].box)
    if share < th.inside_fraction - th.inside_band + SHARE_TOL:
        return False
    if not receptacle_ok(w, a, b):
        return None
    return True if share > th.inside_fraction + th.inside_band - SHARE_TOL else None
