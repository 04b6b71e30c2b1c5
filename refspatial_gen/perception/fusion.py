"""Multi-view fusion: 2D detections with masks in posed RGB-D key frames -> one 3D object per instance.

Lifting: a detection's mask, eroded by `ERODE_PX` (mask edges bleed onto the background), is
back-projected with the frame's measured depth; points farther than max(5 cm, 3 x MAD) from the median
depth are another surface seen through or beside the object and are left out; the rest is reduced to a
voxel grid (`voxel`).
Association, frame by frame in key-frame order, detections best score first: a detection joins the
object of its category whose voxels hold the largest share of its own voxels (neighbouring voxels count:
depth noise moves a surface by a voxel), if that share is at least `match_overlap`; an object takes at
most one detection per frame (two boxes in one frame are two objects, as NMS left them). Otherwise it
starts an object. After the last frame, objects of one category whose voxels overlap by half of the
smaller one are merged (an object first seen from two sides that never met). Objects seen in fewer than
`min_views` frames or with fewer than `min_points` voxels are dropped, by reason. Each object keeps its
largest 26-connected voxel component (floaters from depth edges go) and gets a box measured on the lifted
points of those voxels (not on voxel centres: extents on a grid would make distances between objects come
in exact steps that tie with the scene graph's margins): with gravity known, a z-up box from the
minimum-area rectangle of its footprint and the 1st-99th percentile of heights; otherwise the principal axes.
"""

from __future__ import annotations

from collections import Counter
from dataclasses import dataclass, field

import numpy as np

from refspatial_gen.core.camera import Camera
from refspatial_gen.core.geometry import Box3D, rot_z

ERODE_PX = 2
MAX_POINTS = 20000
NEIGHBOURS = np.array([(i, j, k) for i in (-1, 0, 1) for j in (-1, 0, 1) for k in (-1, 0, 1)], np.int64)


@dataclass
class Observation:
    frame: int  # key-frame index
    label: str
    score: float
    codes: np.ndarray  # packed voxel codes of its lifted points (pack)
    mask: np.ndarray | None = None
    bbox: tuple[float, float, float, float] | None = None
    points: np.ndarray | None = None  # the lifted points themselves (N, 3): boxes are measured on them


@dataclass
class FusedObject:
    label: str
    voxels: np.ndarray  # packed voxel codes (pack), sorted unique
    frames: list[int] = field(default_factory=list)
    scores: list[float] = field(default_factory=list)
    observations: list[Observation] = field(default_factory=list)


def lift(
    mask: np.ndarray, depth: np.ndarray, cam: Camera, voxel: float, max_points: int = MAX_POINTS
) -> tuple[np.ndarray, np.ndarray]:
    """(packed voxel codes, world points) of a mask's pixels with depth, cleaned as the module docstring
    says (at most `max_points` pixels, every k-th in row order, so a large mask costs what a small one does)."""
    import cv2

    m = cv2.erode(mask.astype(np.uint8), np.ones((2 * ERODE_PX + 1,) * 2, np.uint8)).astype(bool)
    if m.sum() < 20:
        m = mask.astype(bool)
    ys, xs = np.nonzero(m & (depth > 0))
    if len(ys) == 0:
        return np.zeros(0, np.int64), np.zeros((0, 3))
    step = int(np.ceil(len(ys) / max_points))
    ys, xs = ys[::step], xs[::step]
    z = depth[ys, xs].astype(np.float64)
    med = float(np.median(z))
    mad = float(np.median(np.abs(z - med)))
    keep = np.abs(z - med) <= max(0.05, 3.0 * 1.4826 * mad)
    pts = cam.cam_to_world(cam.backproject(xs[keep] + 0.5, ys[keep] + 0.5, z[keep]))
    return pack(voxel_keys(pts, voxel)), pts


def voxel_keys(pts: np.ndarray, voxel: float) -> np.ndarray:
    return np.floor(np.asarray(pts, float) / voxel).astype(np.int64)


_OFF = 1 << 20  # voxel indices within +-2^20 (+-20 km at 2 cm) pack into one int64


def pack(keys: np.ndarray) -> np.ndarray:
    """(N, 3) integer voxel keys -> sorted unique int64 codes."""
    k = np.asarray(keys, np.int64).reshape(-1, 3) + _OFF
    return np.unique((k[:, 0] << 42) | (k[:, 1] << 21) | k[:, 2])


def unpack(codes: np.ndarray) -> np.ndarray:
    c = np.asarray(codes, np.int64)
    return np.stack([(c >> 42) & 0x1FFFFF, (c >> 21) & 0x1FFFFF, c & 0x1FFFFF], axis=1) - _OFF


def near(codes: np.ndarray, others: np.ndarray) -> np.ndarray:
    """For each code, whether it or one of its 26 neighbours is in `others` (sorted unique codes)."""
    hit = np.zeros(len(codes), bool)
    if len(codes) == 0 or len(others) == 0:
        return hit
    base = unpack(codes)
    n = len(others)
    for off in NEIGHBOURS:
        nb = pack_unsorted(base + off)
        j = np.minimum(np.searchsorted(others, nb), n - 1)
        hit |= others[j] == nb
    return hit


def associate(observations: list[Observation], voxel: float, match_overlap: float) -> list[FusedObject]:
    """Greedy frame-by-frame association (see the module docstring)."""
    objects: list[FusedObject] = []
    for f in sorted({o.frame for o in observations}):
        frame_obs = sorted((o for o in observations if o.frame == f), key=lambda o: (-o.score, o.label, o.bbox or ()))
        used: set[int] = set()
        for o in frame_obs:
            keys = o.codes
            if len(keys) == 0:
                continue
            best, best_share = -1, 0.0
            for k, obj in enumerate(objects):
                if obj.label != o.label or k in used:
                    continue
                share = float(near(keys, obj.voxels).mean())
                if share > best_share:
                    best, best_share = k, share
            if best >= 0 and best_share >= match_overlap:
                obj = objects[best]
                obj.voxels = np.union1d(obj.voxels, keys)
            else:
                obj = FusedObject(o.label, keys)
                objects.append(obj)
                best = len(objects) - 1
            used.add(best)
            obj.frames.append(f)
            obj.scores.append(o.score)
            obj.observations.append(o)
    return _merge_split(objects)


def _merge_split(objects: list[FusedObject]) -> list[FusedObject]:
    merged = True
    while merged:
        merged = False
        for i in range(len(objects)):
            for j in range(i + 1, len(objects)):
                a, b = objects[i], objects[j]
                if a.label != b.label or set(a.frames) & set(b.frames):
                    continue
                small = min(len(a.voxels), len(b.voxels))
                if small and near(b.voxels, a.voxels).sum() >= 0.5 * small:
                    a.voxels = np.union1d(a.voxels, b.voxels)
                    a.frames += b.frames
                    a.scores += b.scores
                    a.observations += b.observations
                    del objects[j]
                    merged = True
                    break
            if merged:
                break
    return objects


def largest_component(keys: np.ndarray) -> np.ndarray:
    """The largest 26-connected component of integer voxel keys (ties: the lowest component label, i.e.
    the one holding the smallest code), via a sparse neighbour graph (no dense grid)."""
    from scipy.sparse import coo_matrix
    from scipy.sparse.csgraph import connected_components

    codes = pack(keys)
    n = len(codes)
    if n < 2:
        return unpack(codes)
    rows, cols = [], []
    base = unpack(codes)
    for off in NEIGHBOURS:
        if not off.any():
            continue
        nb = pack_unsorted(base + off)
        j = np.searchsorted(codes, nb)
        ok = (j < n) & (codes[np.minimum(j, n - 1)] == nb)
        rows.append(np.nonzero(ok)[0])
        cols.append(j[ok])
    r, c = np.concatenate(rows), np.concatenate(cols)
    g = coo_matrix((np.ones(len(r), np.int8), (r, c)), shape=(n, n))
    _, lab = connected_components(g, directed=False)
    counts = np.bincount(lab)
    return unpack(codes[lab == int(np.argmax(counts))])


def pack_unsorted(keys: np.ndarray) -> np.ndarray:
    k = np.asarray(keys, np.int64).reshape(-1, 3) + _OFF
    return (k[:, 0] << 42) | (k[:, 1] << 21) | k[:, 2]


def box_of(points: np.ndarray, gravity_known: bool) -> Box3D:
    """A z-up box from the footprint's minimum-area rectangle (gravity known) or the principal axes."""
    import cv2

    if gravity_known:
        z0, z1 = np.percentile(points[:, 2], [1, 99])
        (cx, cy), (w, h), ang = cv2.minAreaRect(points[:, :2].astype(np.float32))
        return Box3D(
            np.array([cx, cy, (z0 + z1) / 2]),
            np.array([max(w, 1e-3), max(h, 1e-3), max(z1 - z0, 1e-3)]),
            rot_z(np.deg2rad(ang)),
        )
    c = points.mean(axis=0)
    _, _, vt = np.linalg.svd(points - c, full_matrices=False)
    R = vt.T
    if np.linalg.det(R) < 0:
        R[:, 2] *= -1
    local = (points - c) @ R
    lo, hi = np.percentile(local, 1, axis=0), np.percentile(local, 99, axis=0)
    return Box3D(c + R @ ((lo + hi) / 2), np.maximum(hi - lo, 1e-3), R)


def finish(
    objects: list[FusedObject], voxel: float, min_views: int, min_points: int, gravity_known: bool
) -> tuple[list[tuple[FusedObject, Box3D]], dict[str, int]]:
    """Kept objects with their boxes (ordered by label, then position) and drop counts by reason. Boxes are
    measured on the lifted points of the kept voxels (voxel centres would put every extent on the grid,
    so distances between objects would come in exact steps and tie with the scene graph's margins)."""
    drops: Counter = Counter()
    out = []
    for obj in objects:
        if len(set(obj.frames)) < min_views:
            drops["fusion_too_few_views"] += 1
            continue
        keys = largest_component(unpack(obj.voxels))
        if len(keys) < min_points:
            drops["fusion_too_few_points"] += 1
            continue
        pts = [o.points for o in obj.observations if o.points is not None and len(o.points)]
        if pts:
            allp = np.concatenate(pts)
            pts_kept = allp[np.isin(pack_unsorted(voxel_keys(allp, voxel)), pack(keys))]
        else:
            pts_kept = (keys + 0.5) * voxel
        out.append((obj, box_of(pts_kept, gravity_known)))
    out.sort(key=lambda x: (x[0].label, tuple(np.round(x[1].center, 4))))
    return out, dict(sorted(drops.items()))
