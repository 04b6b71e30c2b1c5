"""The answer point of a corner or edge free region lies at its corner / along its edge (audit round 5).

Why: the answer point of a free region is its visible sample farthest inside the region (graph/freespace.py).
In a corner patch that is the patch's inner corner, the point of the patch FARTHEST from the named corner: on a
shallow cabinet top "the near-left corner" got a point 46% of the way back from the front edge. So, for a
corner region, the point is the clear sample NEAREST the named corner, and for an edge region the one farthest
inside the band among those near the edge; neither may lie farther from its corner / edge than
`corner_point_max_share` (recipe `graph: thresholds:`, graph/constants.py) of the surface's extent along each
side (corner) or across the edge (edge). A region with no clear point that near is withheld and counted in
graph.meta["truth"] (`corner_point_far`, `edge_point_far`). verify re-checks the stored point's share from the
stored surface box, camera and gravity by its own code (qa/verify_spotpoint.py).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

FAR = {"corner": "corner_point_far", "edge": "edge_point_far"}  # graph.meta["truth"] reasons


@dataclass(frozen=True)
class Spot:
    """A named corner (two sides from its vertex) or edge (one inward axis from its line) of a surface."""

    kind: str  # "corner" | "edge"
    origin: np.ndarray  # (2,) the corner vertex, or a point of the edge line
    axes: np.ndarray  # (k, 2) unit axes into the surface: the two sides (corner) or the inward normal (edge)
    extents: np.ndarray  # (k,) the surface's extent along each axis (m)

    def shares(self, xy: np.ndarray) -> np.ndarray:
        """Largest share of the surface's extent by which each point lies from the corner / edge, per axis."""
        d = (np.asarray(xy, float).reshape(-1, 2) - self.origin) @ self.axes.T
        return np.max(np.abs(d) / np.maximum(self.extents, 1e-9), axis=1)


def corner_spot(poly: np.ndarray, k: int) -> Spot:
    """The corner at vertex k of the surface outline `poly` (4x2, a rectangle in order)."""
    p = np.asarray(poly[k], float)
    sides = np.array([poly[(k + 1) % 4] - p, poly[(k - 1) % 4] - p], float)
    lengths = np.linalg.norm(sides, axis=1)
    return Spot("corner", p, sides / np.maximum(lengths, 1e-12)[:, None], lengths)


def edge_spot(poly: np.ndarray, a: np.ndarray, b: np.ndarray) -> Spot:
    """The edge a->b of the surface outline `poly`, its inward axis towards the rest of the surface."""
    a = np.asarray(a, float)
    e = (np.asarray(b, float) - a) / max(float(np.linalg.norm(np.asarray(b, float) - a)), 1e-12)
    inward = np.array([-e[1], e[0]])
    reach = (np.asarray(poly, float) - a) @ inward
    if abs(reach.min()) > abs(reach.max()):  # the surface lies on the other side
        inward, reach = -inward, -reach
    return Spot("edge", a, inward[None, :], np.array([max(float(reach.max()), 1e-9)]))


def point_order(spot: Spot, xy: np.ndarray, clear: np.ndarray, depth_in: np.ndarray, max_share: float) -> list[int]:
    """Sample indices to try as the answer point: clear ones within `max_share` of the spot, a corner's nearest
    to its vertex first (share, then distance), an edge's farthest inside the band first (as other regions)."""
    share = np.round(spot.shares(xy), 6)
    ok = np.flatnonzero(clear & (share <= max_share))
    if spot.kind == "corner":
        dist = np.round(np.linalg.norm(xy[ok] - spot.origin, axis=1), 6)
        return [int(ok[i]) for i in np.lexsort((dist, share[ok]))]
    return [int(ok[i]) for i in np.argsort(-np.round(depth_in[ok], 6), kind="stable")]
