"""Unannotated things standing on the floor of a point-cloud scan: where the floor is not free.

A free-space answer needs the depth map to see the floor there, and obstacles are annotated objects
only: the floor between the legs of an unannotated office chair passes both tests. The scan's points
say more: points above the floor that no annotated box (and no labelled instance with a box) explains
are something. Their low points (up to `LOW` above the floor) are clustered on the floor plane; each
cluster of at least `min_points` is a floor-standing thing whose footprint is its convex hull grown by
`GROW` point spacings (a sparse cloud misses the tips of the legs). Floor pixels inside such a footprint
get unknown depth (0): nothing is claimed there, so no free-space point (and no depth question) lands
on it. The count is in
`frame.meta["unexplained_floor_pixels"]`.
"""

from __future__ import annotations

import numpy as np

from refspatial_gen.core.camera import Camera

LOW = 0.3  # m above the floor: the band whose unexplained points make a footprint
FLOOR_BAND = 0.05  # m: depth pixels this close to the floor are "floor" inside a footprint
GROW = 5.0  # footprints grow by this many point spacings: a sparse cloud misses the tips of legs


def unexplained_points(
    points: np.ndarray,
    boxes: list,
    floor_z: float,
    labels: np.ndarray | None = None,
    box_instance: dict[int, int] | None = None,
    structural: set[int] | None = None,
    pad: float = 0.03,
) -> np.ndarray:
    """Points above the floor that no annotated object explains: outside every padded box or, with
    labels, of an instance that is no box's (structural instances, walls and floors, explain themselves)."""
    P = np.asarray(points, float)
    above = P[:, 2] > floor_z + 0.03
    inside = np.zeros(len(P), bool)
    for b in boxes:
        inside |= b.box.contains(P, pad)
    if labels is None:
        return above & ~inside
    known = np.isin(labels, np.array(sorted(set((box_instance or {}).values()) | set(structural or ())), np.int64))
    return above & ~(known | ((labels <= 0) & inside))


def floor_footprints(points: np.ndarray, unexplained: np.ndarray, floor_z: float, spacing: float, min_points: int = 20):
    """Convex hulls (shapely, grown by GROW spacings) of the clusters of low unexplained points."""
    from scipy.sparse import coo_matrix
    from scipy.sparse.csgraph import connected_components
    from scipy.spatial import cKDTree
    from shapely.geometry import MultiPoint

    P = np.asarray(points, float)[unexplained]
    low = P[P[:, 2] < floor_z + LOW]
    if len(low) < min_points or spacing <= 0:
        return []
    pairs = cKDTree(low[:, :2]).query_pairs(2.5 * spacing, output_type="ndarray")
    A = coo_matrix((np.ones(len(pairs)), (pairs[:, 0], pairs[:, 1])), shape=(len(low), len(low)))
    _, lab = connected_components(A, directed=False)
    out = []
    for c in np.flatnonzero(np.bincount(lab) >= min_points):
        q = low[lab == c, :2]
        out.append(MultiPoint([tuple(map(float, x)) for x in q]).convex_hull.buffer(GROW * spacing))
    return out


def withhold_floor(depth: np.ndarray, cam: Camera, footprints: list, floor_z: float) -> int:
    """Set depth 0 on floor pixels inside any footprint (in place); returns how many."""
    import shapely

    if not footprints:
        return 0
    H, W = depth.shape
    vs, us = np.nonzero(depth > 0)
    world = cam.cam_to_world(cam.backproject(us + 0.5, vs + 0.5, depth[vs, us]))
    floor = np.abs(world[:, 2] - floor_z) < FLOOR_BAND
    hit = np.zeros(len(vs), bool)
    union = shapely.union_all(footprints)
    hit[floor] = shapely.contains_xy(union, world[floor, 0], world[floor, 1])
    depth[vs[hit], us[hit]] = 0.0
    return int(hit.sum())
