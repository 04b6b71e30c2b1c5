"""Free-space regions on support surfaces, and the checker every free-space answer must pass.

Regions (shared/spec/relations.md): for an anchor standing on a surface, the 90-degree sectors left of /
right of / in front of / behind it (as the viewer sees them; radius half-diagonal + max(diagonal,
free_radius_min)); the area between two anchors on the same surface (hull of their footprints); the
corners and edges of the surface, named from the viewer. Obstacle footprints (every object standing on
or over the surface, grown by a clearance) are subtracted, the region is cut to the part of the surface
the camera's image covers, points are kept only when the depth map sees the surface there (2.5 cm), and
a region needs a minimum visible area. The answer point is the visible sample farthest inside the region
that keeps a clearance (`clear_samples`): `graph: truth: min_point_clearance_px` (20 px at 640x480) from every
object's mask (but the surface's own object) and from the image border, and the thresholds' `free_clearance`
from every obstacle footprint; it is re-checked after rounding to RefSpatial's three decimals with
`check_free_point` and the clearance again. A region with no such point is dropped (graph.meta["truth"]:
`free_point_no_clearance`). Audit round 2: a point "behind the mug" touched the mug in the image. A corner or
edge region's point is instead the clear one nearest its corner / within a band of its edge (graph/corner_point.py).
"""

from __future__ import annotations

from typing import Any

import numpy as np
import shapely
from shapely.geometry import Polygon
from shapely.ops import unary_union

from refspatial_gen.core.mask import denormalise_point, normalise_point
from refspatial_gen.core.model import Frame, FreeSpaceRegion, SceneGraph
from refspatial_gen.graph.clearance import clear_samples
from refspatial_gen.graph.corner_point import FAR, Spot, corner_spot, edge_spot, point_order
from refspatial_gen.graph.scene import SceneGeom, box_footprint, points_in_polygons
from refspatial_gen.graph.support import get_supports, surface_polygon

MAX_SAMPLES = 3000  # grid points per region (the grid coarsens for large regions)
POINT_TRIES = 12
OBSTACLE_HEIGHT = 0.005  # an object reaching this far above the surface blocks it
MAX_BETWEEN_GAP = {"tabletop": 0.6, "room": 3.0}
MIN_BETWEEN_GAP_FACTOR = 2.0
BETWEEN_NEIGHBOURS = 3  # "between" regions for each anchor and its nearest neighbours only
SIMPLIFY = 0.003  # m, stored outlines are simplified by this much (the checker uses the stored outline)
NO_CLEARANCE = "free_point_no_clearance"  # graph.meta["truth"]: a region dropped for want of a clear point


# ----------------------------------------------------------------------------- shared geometry
def gravity_rotation(graph_or_geom: Any) -> np.ndarray:
    if isinstance(graph_or_geom, SceneGeom):
        return graph_or_geom.gravity.rotation
    g = graph_or_geom.meta.get("gravity", {})
    return np.array(g["rotation"], float) if "rotation" in g else np.eye(3)


def pixel_to_plane(frame: Frame, G: np.ndarray, px: float, py: float, z: float) -> np.ndarray | None:
    """Gravity-world point where the ray through pixel centre (px, py) meets the plane at height z."""
    cam = frame.camera
    R = G @ cam.world_from_cam[:3, :3]
    o = G @ cam.world_from_cam[:3, 3]
    d_cam = np.array([(px + 0.5 - cam.cx) / cam.fx, (py + 0.5 - cam.cy) / cam.fy, 1.0])
    d = R @ d_cam
    if abs(d[2]) < 1e-12:
        return None
    t = (z - o[2]) / d[2]
    if t <= 0:
        return None
    return o + t * d


def obstacle_footprints(frame: Frame, G: np.ndarray, z: float, gap: float) -> list[np.ndarray]:
    """Footprints of objects standing on or over the plane at height z (bottom within `gap` of it)."""
    out = []
    for o in frame.objects:
        from refspatial_gen.core.geometry import Box3D

        b = Box3D(G @ o.box.center, o.box.size, G @ o.box.rotation)
        lo, hi = b.aabb()
        if lo[2] <= z + gap and hi[2] > z + OBSTACLE_HEIGHT:
            out.append(box_footprint(b)[0])
    return out


def check_free_point(
    frame: Frame,
    graph: SceneGraph,
    region: FreeSpaceRegion,
    point: tuple[float, float] | None = None,
    obstacles: list[np.ndarray] | None = None,
    surface_outline: np.ndarray | None = None,
) -> list[str]:
    """Problems with a free-space answer point (the region's own point by default); [] means valid.

    Checks: inside the image; the pixel's ray meets the surface plane in front of the camera; the hit
    lies on the support surface, inside the region, outside every obstacle footprint; and the depth map
    agrees with the surface there within the visibility tolerance. `obstacles` (footprints) may be
    passed in when many points of one frame are checked; by default they are computed from the frame.
    `surface_outline` (the region's surface polygon in the gravity world, 4x2 CCW) likewise.
    """
    th = graph.meta.get("thresholds", {})
    tol = float(th.get("visibility_tolerance", 0.025))
    gap = float(th.get("support_gap", 0.05))
    p = region.point if point is None else point
    cam = frame.camera
    problems = []
    if not (0.0 <= p[0] < 1.0 and 0.0 <= p[1] < 1.0):
        return [f"point {p} outside the image"]
    px, py = denormalise_point(p[0], p[1], cam.width, cam.height)
    G = gravity_rotation(graph)
    hit = pixel_to_plane(frame, G, px, py, region.z)
    if hit is None:
        return [f"pixel ({px}, {py}) does not see the plane z={region.z:.3f}"]
    if surface_outline is None:
        surf = {s.id: s for s in frame.surfaces}.get(region.surface_id)
        if surf is not None:
            from refspatial_gen.core.geometry import Box3D

            surface_outline = surface_polygon(Box3D(G @ surf.box.center, surf.box.size, G @ surf.box.rotation))
    if surface_outline is None:
        problems.append(f"unknown surface {region.surface_id!r}")
    elif not points_in_polygons(hit[None, :2], surface_outline[None])[0, 0]:
        problems.append(f"point ({hit[0]:.3f}, {hit[1]:.3f}) is off surface {region.surface_id}")
    if not shapely.contains_xy(shapely.polygons(np.asarray(region.polygon_xy, float)), hit[0], hit[1]):
        problems.append("point is outside the region polygon")
    fps = obstacle_footprints(frame, G, region.z, gap) if obstacles is None else obstacles
    if len(fps) and points_in_polygons(hit[None, :2], np.asarray(fps, float)).any():
        problems.append(f"point ({hit[0]:.3f}, {hit[1]:.3f}) lies on an obstacle's footprint")
    pw = G.T @ hit
    z_cam = float(cam.world_to_cam(pw[None])[0, 2])
    d = float(frame.depth[py, px])
    if not (d > 0 and abs(d - z_cam) <= tol):
        problems.append(f"not visible: depth map {d:.3f} m vs surface {z_cam:.3f} m at pixel ({px}, {py})")
    return problems


# ----------------------------------------------------------------------------- region construction
def _obstacles(geom: SceneGeom, z: float, gap: float) -> list[np.ndarray]:
    """`obstacle_footprints` from the geometry's precomputed gravity-world boxes (same boxes, same test)."""
    keep = (geom.lo[:, 2] <= z + gap) & (geom.hi[:, 2] > z + OBSTACLE_HEIGHT)
    return [geom.footprints[i] for i in np.flatnonzero(keep)]


def _view_polygon(geom: SceneGeom, z: float) -> Polygon | None:
    """The part of the plane at height z that the image covers."""
    if "_view_rays" not in geom.cache:  # the border rays do not depend on the plane: one set per frame
        W, H = geom.W, geom.H
        k = 12
        border = (
            [(x, 0) for x in np.linspace(0, W - 1, k)]
            + [(W - 1, y) for y in np.linspace(0, H - 1, k)]
            + [(x, H - 1) for x in np.linspace(W - 1, 0, k)]
            + [(0, y) for y in np.linspace(H - 1, 0, k)]
        )
        cam, G = geom.frame.camera, geom.gravity.rotation
        R, o = G @ cam.world_from_cam[:3, :3], G @ cam.world_from_cam[:3, 3]
        # one matrix-vector product per pixel, as pixel_to_plane does, so the hull matches its rays bit for bit
        rays = np.array(
            [R @ np.array([(x + 0.5 - cam.cx) / cam.fx, (y + 0.5 - cam.cy) / cam.fy, 1.0]) for x, y in border]
        )
        geom.cache["_view_rays"] = (o, rays)
    o, d = geom.cache["_view_rays"]
    ok = np.abs(d[:, 2]) >= 1e-12
    t = (z - o[2]) / np.where(ok, d[:, 2], 1.0)
    hits = o + t[:, None] * d  # elementwise, as pixel_to_plane's o + t * d
    pts = [p[:2] for p, good in zip(hits, ok & (t > 0)) if good and np.linalg.norm(p - geom.cam_pos_g) < 50.0]
    if len(pts) < 3:
        return None
    return shapely.convex_hull(shapely.multipoints(np.array(pts)))


def _largest(g: Any) -> Polygon | None:
    if g is None or g.is_empty:
        return None
    if isinstance(g, Polygon):
        return g
    polys = [p for p in getattr(g, "geoms", []) if isinstance(p, Polygon)]
    if not polys:
        return None
    return max(polys, key=lambda p: (round(p.area, 9), p.centroid.x, p.centroid.y))


_WEDGE_SPREAD = np.linspace(-np.pi / 4, np.pi / 4, 9)


def _wedge(apex: np.ndarray, direction: np.ndarray, radius: float, k: int = 9) -> Polygon:
    ang = np.arctan2(direction[1], direction[0])
    a = ang + (_WEDGE_SPREAD if k == 9 else np.linspace(-np.pi / 4, np.pi / 4, k))
    arc = apex + radius * np.stack([np.cos(a), np.sin(a)], axis=1)
    return shapely.polygons(np.vstack([apex, arc]))


def _sample_area_bound(poly: Polygon, min_step: float) -> float:
    """An upper bound on `len(samples) * step**2` from `_visible_samples`, from the outline alone.

    Each sample owns a disjoint step x step grid cell centred inside `poly`, so every cell lies within
    r = step/sqrt(2) of the polygon: the cells' total area is at most area + perimeter * r + (vertices) *
    pi * r**2 (the r-neighbourhood: a strip along every edge and a disc at every vertex). The step grows
    with the area (MAX_SAMPLES), so the bound uses the larger of both candidate steps.
    """
    step = max(min_step, float(np.sqrt(poly.area / MAX_SAMPLES)))
    r = step / np.sqrt(2.0)
    nv = int(shapely.get_num_coordinates(poly))
    return poly.area + poly.length * r + nv * np.pi * r * r


def _visible_samples(geom: SceneGeom, poly: Polygon, z: float, min_area: float = 0.0) -> tuple[np.ndarray, float]:
    """Grid points of `poly` that the camera sees on the plane at height z, and the grid cell size.
    Returns no points as soon as fewer than `min_area / step**2` grid points lie inside `poly` (the caller
    rejects such regions anyway), skipping the projection."""
    step = geom.th.free_grid
    step = max(step, float(np.sqrt(poly.area / MAX_SAMPLES)))
    x0, y0, x1, y1 = poly.bounds
    xs = np.arange(x0 + step / 2, x1, step)
    ys = np.arange(y0 + step / 2, y1, step)
    if not len(xs) or not len(ys):
        return np.zeros((0, 2)), step
    pts = np.empty((len(ys) * len(xs), 2))  # the meshgrid(xs, ys) points, row by row
    pts[:, 0] = np.tile(xs, len(ys))
    pts[:, 1] = np.repeat(ys, len(xs))
    shapely.prepare(poly)
    pts = pts[shapely.contains_xy(poly, pts[:, 0], pts[:, 1])]
    if not len(pts) or len(pts) * step * step < min_area:
        return pts[:0], step
    uv, zc = geom.project_world(np.column_stack([pts, np.full(len(pts), z)]))
    W, H = geom.W, geom.H
    ok = np.isfinite(uv).all(axis=1) & (zc > 0)
    u = np.floor(np.where(ok, uv[:, 0], -1)).astype(int)
    v = np.floor(np.where(ok, uv[:, 1], -1)).astype(int)
    ok &= (u >= 0) & (u < W) & (v >= 0) & (v < H)
    d = np.zeros(len(pts))
    d[ok] = geom.frame.depth[v[ok], u[ok]]
    ok &= (d > 0) & (np.abs(d - zc) <= geom.th.visibility_tolerance)
    return pts[ok], step


def _region(
    geom: SceneGeom,
    graph_stub: SceneGraph,
    sid: str,
    kind: str,
    anchors: tuple[Any, ...],
    poly: Polygon,
    z: float,
    label: str,
    obstacles: list[np.ndarray],
    outline: np.ndarray,
    spot: Spot | None = None,
) -> FreeSpaceRegion | None:
    poly = poly.simplify(SIMPLIFY, preserve_topology=True)
    if not isinstance(poly, Polygon) or poly.is_empty:
        return None
    if _sample_area_bound(poly, geom.th.free_grid) < geom.th.free_min_area:
        return None  # too small whatever the visibility: skip the sampling
    vis, step = _visible_samples(geom, poly, z, geom.th.free_min_area)
    area = len(vis) * step * step
    if area < geom.th.free_min_area:
        return None
    depth_in = shapely.distance(shapely.points(vis), poly.exterior)
    exclude = next((su.object_id for su in geom.surfaces if su.id == sid), None)
    uv_all, _ = geom.project_world(np.column_stack([vis, np.full(len(vis), z)]))
    clear = clear_samples(geom, np.floor(uv_all).astype(int), vis, exclude, obstacles)
    if not clear.any():
        counts = geom.cache.setdefault("truth", {})
        counts[NO_CLEARANCE] = counts.get(NO_CLEARANCE, 0) + 1
        return None
    share = geom.th.corner_point_max_share
    if spot is None:
        order = [k for k in np.argsort(-np.round(depth_in, 6), kind="stable") if clear[k]]
    elif not (order := point_order(spot, vis, clear, depth_in, share)):
        counts = geom.cache.setdefault("truth", {})  # corner_point.py: no clear point near the corner / edge
        counts[FAR[spot.kind]] = counts.get(FAR[spot.kind], 0) + 1
        return None
    G = geom.gravity.rotation
    poly_xy = [(round(float(x), 5), round(float(y), 5)) for x, y in np.asarray(poly.exterior.coords)[:-1]]
    for k in order[:POINT_TRIES]:
        p = normalise_point(float(np.floor(uv_all[k, 0])), float(np.floor(uv_all[k, 1])), geom.W, geom.H)
        px, py = denormalise_point(p[0], p[1], geom.W, geom.H)
        hit = pixel_to_plane(geom.frame, G, px, py, z)
        if hit is None or not clear_samples(geom, np.array([[px, py]]), hit[None, :2], exclude, obstacles)[0]:
            continue
        if spot is not None and spot.shares(hit[None, :2])[0] > share:
            continue  # the rounded point drifted past the corner's / edge's share
        r = FreeSpaceRegion(
            sid, kind, tuple(anchors), poly_xy, z, round(area, 6), (float(hit[0]), float(hit[1]), float(z)), p, label
        )
        if not check_free_point(geom.frame, graph_stub, r, obstacles=obstacles, surface_outline=outline):
            return r
    return None


def free_regions(geom: SceneGeom) -> list[FreeSpaceRegion]:
    """All free-space regions of the frame (cached per geometry)."""
    if "free_regions" in geom.cache:
        return geom.cache["free_regions"]
    out: list[FreeSpaceRegion] = []
    if geom.world_ok:
        out = _build(geom)
    geom.cache["free_regions"] = out
    return out


def _build(geom: SceneGeom) -> list[FreeSpaceRegion]:
    from refspatial_gen.graph.relations.surface import surface_labels

    supports, _roots = get_supports(geom)
    labels = surface_labels(geom)
    meta = {"thresholds": geom.th.to_json(), "gravity": {"rotation": geom.gravity.rotation.tolist()}}
    stub = SceneGraph(geom.frame.frame_id, [], [], [], meta)
    out: list[FreeSpaceRegion] = []
    for s in geom.surfaces:
        if not labels.get(s.id, {}).get("unseen"):  # no free space on a top a person cannot see
            out += _surface_regions(geom, s, supports, labels.get(s.id, {}), stub)
    return out


def _surface_regions(
    geom: SceneGeom, s: Any, supports: Any, lab: dict[str, Any], stub: SceneGraph
) -> list[FreeSpaceRegion]:
    """The free regions of one support surface: beside each object standing on it (left/right/front/behind),
    between neighbouring objects, and in its labelled corners and along its labelled edges."""
    th = geom.th
    z = s.top_z
    surf = Polygon(surface_polygon(s.box)).buffer(-th.free_clearance, join_style="mitre")
    view = _view_polygon(geom, z)
    if surf.is_empty or view is None:
        return []
    obst_fp = _obstacles(geom, z, th.support_gap)
    outline = surface_polygon(s.box)
    obst = (
        list(shapely.buffer(shapely.polygons(np.asarray(obst_fp, float)), th.free_clearance, join_style="mitre"))
        if obst_fp
        else []
    )
    free = surf.intersection(view)
    if obst:
        free = free.difference(unary_union(obst))
    if free.is_empty:
        return []
    out: list[FreeSpaceRegion] = []

    def add(kind: str, anchors: tuple[int, ...], shape: Any, label: str = "", spot: Spot | None = None) -> None:
        poly = _largest(free.intersection(shape))
        if poly is not None:
            r = _region(geom, stub, s.id, kind, anchors, poly, z, label, obst_fp, outline, spot)
            if r is not None:
                out.append(r)

    on_s = [
        i
        for i in np.argsort(geom.ids, kind="stable")
        if supports[i] is not None and supports[i].kind == "surface" and supports[i].ref == s.id
    ]
    axes = geom.camera_axes_horizontal()
    if axes is not None:
        right, fwd = axes
        dirs = (("left_of", -right[:2]), ("right_of", right[:2]), ("in_front_of", -fwd[:2]), ("behind", fwd[:2]))
        for i in on_s:
            fp = geom.footprints[i]
            diag = float(np.linalg.norm(fp[2] - fp[0]))
            radius = diag / 2 + max(diag, th.free_radius_min)
            for kind, d in dirs:
                add(kind, (int(geom.ids[i]),), _wedge(geom.centers[i, :2], d, radius))
    for i, j in _between_pairs(geom, on_s):
        hull = shapely.convex_hull(shapely.MultiPoint(np.vstack([geom.footprints[i], geom.footprints[j]])))
        add("between", (int(geom.ids[i]), int(geom.ids[j])), hull)
    spoly: Any = lab.get("polygon")
    for name, p in sorted(lab.get("corners", {}).items()):
        k = int(np.argmin(np.linalg.norm(spoly - p, axis=1)))
        e1 = spoly[(k + 1) % 4] - p
        e2 = spoly[(k - 1) % 4] - p
        e1 = e1 / np.linalg.norm(e1) * min(th.corner_size, np.linalg.norm(e1) / 2)
        e2 = e2 / np.linalg.norm(e2) * min(th.corner_size, np.linalg.norm(e2) / 2)
        shape = shapely.polygons(np.array([p, p + e1, p + e1 + e2, p + e2]))
        add("corner", (), shape, f"{name} corner", corner_spot(spoly, k))
    for name, (a, b) in sorted(lab.get("edges", {}).items()):
        e = (b - a) / np.linalg.norm(b - a)
        inward = np.array([-e[1], e[0]])
        w = min(th.edge_width, float(np.linalg.norm(b - a)) / 2)
        shape = shapely.polygons(np.array([a, b, b + inward * w, a + inward * w]))
        add("edge", (), shape, name, edge_spot(spoly, a, b))
    return out


def _between_pairs(geom: SceneGeom, on_s: list[Any]) -> list[tuple[int, int]]:
    """Each object on the surface with its nearest neighbours there, at a gap a free spot fits in."""
    th = geom.th
    pairs: set[tuple[int, ...]] = set()
    for i in on_s:
        near = sorted((j for j in on_s if j != i), key=lambda j: (geom.surface_distance[i, j], int(geom.ids[j])))
        pairs.update(tuple(sorted((int(i), int(j)), key=lambda k: int(geom.ids[k]))) for j in near[:BETWEEN_NEIGHBOURS])
    out = []
    for i, j in sorted(pairs, key=lambda p: (int(geom.ids[p[0]]), int(geom.ids[p[1]]))):
        gapd = geom.surface_distance[i, j]
        if (
            gapd < MIN_BETWEEN_GAP_FACTOR * th.free_clearance * 2
            or gapd > MAX_BETWEEN_GAP[geom.cache.get("scale", "tabletop")]
        ):
            continue
        out.append((i, j))
    return out
