"""Things a scan frame shows that no annotation explains: label completeness from geometry.

Why: SUN RGB-D and ScanNet annotate a fixed class list, not everything in the room (audit round 2: an
office chair at the desk, a white drawer unit beside "the cabinet", a second lamp on the dresser). Every
superlative, ordinal or uniqueness claim ("the cabinet", "the furthest lamp", "the closest object to the
desk") is then only true over the labelled objects, and a person judges it over what they see.

The rule: the frame's depth pixels (every STRIDE-th; sensor depth or the splatted point cloud) are lifted
to world points. Those above the floor (`floor_band`), in no annotated box (grown by `box_pad`; with
per-point instance labels, a pixel of an unannotated instance counts even inside a box), not on a large
wall or ceiling plane (seeded RANSAC; vertical or overhead, both in-plane extents over `plane_extent`)
and not BEYOND one (a mirror's reflection, the view through a window) are linked into clusters (points
closer than `link`, clusters whose boxes nearly touch merged). A cluster covering `min_area` of the image
and `min_extent` metres across is an unlabelled blob.

Each blob enters the frame as one faint *stand-in* object per category the frame names that a person
could take it for (`could_be`: size and height plausible by truth/data/category_sizes.yaml), with the
blob's pixels as mask, its points' box, `visible_fraction` 0 and `provenance["distractor_only"]`. The
visibility floor (graph/visibility.py) gives a stand-in no phrase and no answer point, but it still
counts: "the cabinet" is not unique where a blob could be a cabinet (the phrase must then single the
real one out over the stand-ins too), and qa/faint.py withholds every pair whose answer a stand-in could
change ("the furthest lamp", "the closest object to the desk"). An object whose label does not say what
its mask is (truth/labels.py) is made a distractor the same way, with stand-ins for what it may show.
Counted in `frame.meta["truth"]`: `unlabelled_blobs`, `unlabelled_stand_ins`, `unreliable_label`,
`unreliable_label_stand_ins`; the pairs withheld are counted by qa/faint.py's reasons.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

import numpy as np

from refspatial_gen.core.camera import Camera
from refspatial_gen.core.geometry import Box3D
from refspatial_gen.core.mask import RLE
from refspatial_gen.core.model import ObjectInstance

STRIDE = 2  # pixels: the blob search works on every 2nd row and column
BEYOND = 0.5  # m: points this far behind a wall plane are outside the room (a mirror's reflection, a window)
MAX_PLANES = 6  # at most this many wall/floor/ceiling planes are taken away
PLANE_TOL = 0.03  # m: a point this close to a plane is on it
RANSAC_ITERATIONS = 200
MERGE_MIN_POINTS = 5  # clusters this small are noise: they do not merge others
MERGE_GAP = 2.0  # clusters whose boxes come closer than this many links are one thing
WALL_COS = 0.26  # |normal z| below this: a vertical plane (wall); above 1 - this/10: floor or ceiling
SEEN_SHARE = 1.0  # a blob smaller than this share of a category's smallest extent is not taken for one
FLOOR_THING = 0.2  # m: categories at least this tall stand on the floor (a blob above their reach is not one)
STAND_IN_ID = 100000  # stand-in ids start here (annotation ids are far smaller)


@dataclass(frozen=True)
class BlobParams:
    min_area: float = 0.004  # share of the image a blob must cover
    min_extent: float = 0.15  # m: its largest extent must reach this
    box_pad: float = 0.05  # m: points this close to an annotated box are explained by it
    plane_extent: float = 1.0  # m: a plane wider and taller than this is a wall, floor or ceiling
    link: float = 0.06  # m: points closer than this belong to one cluster
    floor_band: float = 0.08  # m: points this close above the floor are floor


@dataclass
class Blob:
    mask: np.ndarray  # (H, W) bool
    box: Box3D  # gravity-aligned box of its points (2-98th percentiles)
    pixels: int


def _lift(cam: Camera, depth: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    vs, us = np.mgrid[0 : cam.height : STRIDE, 0 : cam.width : STRIDE]
    z = depth[::STRIDE, ::STRIDE]
    ok = z > 0
    us, vs = us[ok], vs[ok]
    return us, vs, cam.cam_to_world(cam.backproject(us + 0.5, vs + 0.5, z[ok]))


def _plane(P: np.ndarray, rng: np.random.Generator) -> tuple[np.ndarray, np.ndarray]:
    """RANSAC plane (unit normal, inlier mask) with the most inliers within PLANE_TOL."""
    best_n, best_in = np.array([0.0, 0.0, 1.0]), np.zeros(len(P), bool)
    picks = rng.integers(0, len(P), size=(RANSAC_ITERATIONS, 3))
    for a, b, c in picks:
        n = np.cross(P[b] - P[a], P[c] - P[a])
        norm = float(np.linalg.norm(n))
        if norm < 1e-9:
            continue
        n = n / norm
        inl = np.abs((P - P[a]) @ n) < PLANE_TOL
        if inl.sum() > best_in.sum():
            best_n, best_in = n, inl
    return best_n, best_in


def _in_plane_extent(Q: np.ndarray, n: np.ndarray) -> tuple[float, float]:
    """5-95th percentile extents of points along two axes spanning the plane."""
    a = np.cross(n, [0.0, 0.0, 1.0]) if abs(n[2]) < 0.9 else np.cross(n, [1.0, 0.0, 0.0])
    a /= np.linalg.norm(a)
    b = np.cross(n, a)
    ea, eb = (np.percentile(Q @ ax, 95) - np.percentile(Q @ ax, 5) for ax in (a, b))
    return float(ea), float(eb)


Plane = tuple[np.ndarray, float]  # unit normal towards the camera, offset: n . p = d on the plane


def drop_planes(P: np.ndarray, plane_extent: float, camera: np.ndarray) -> tuple[np.ndarray, list[Plane]]:
    """Mask of the points not on a large wall or ceiling plane and not BEYOND it (a mirror's reflection, a
    window's view are outside the room; books stand only a little behind a shelf's front), and the planes.
    Seeded RANSAC: reproducible. A large horizontal plane below the camera is a bed or table top: it stays."""
    rng = np.random.default_rng(0)
    keep = np.ones(len(P), bool)
    planes: list[Plane] = []
    for _ in range(MAX_PLANES):
        idx = np.flatnonzero(keep)
        if len(idx) < 200:
            break
        n, inl = _plane(P[idx], rng)
        ceiling = abs(n[2]) > 1.0 - WALL_COS / 10 and float(P[idx[inl], 2].mean()) > camera[2]
        if not (abs(n[2]) < WALL_COS or ceiling) or min(_in_plane_extent(P[idx[inl]], n)) < plane_extent:
            break
        d = float(P[idx[inl]].mean(0) @ n)
        if camera @ n < d:  # the normal points to the camera's side
            n, d = -n, -d
        planes.append((n, d))
        keep[idx[inl]] = False
        keep &= P @ n > d - BEYOND
    return keep, planes


def _clusters(P: np.ndarray, link: float) -> np.ndarray:
    """Cluster label per point: points closer than `link` are linked, then clusters whose boxes (grown by
    MERGE_GAP links) overlap are merged (a surface seen at a grazing angle falls apart into slices otherwise)."""
    from scipy.sparse import coo_matrix
    from scipy.sparse.csgraph import connected_components
    from scipy.spatial import cKDTree

    n = len(P)
    pairs = cKDTree(P).query_pairs(link, output_type="ndarray")
    _, lab = connected_components(coo_matrix((np.ones(len(pairs)), (pairs[:, 0], pairs[:, 1])), shape=(n, n)))
    k = int(lab.max()) + 1
    lo = np.full((k, 3), np.inf)
    hi = np.full((k, 3), -np.inf)
    np.minimum.at(lo, lab, P)
    np.maximum.at(hi, lab, P)
    big = np.flatnonzero(np.bincount(lab, minlength=k) >= MERGE_MIN_POINTS)
    gap = MERGE_GAP * link
    over = np.all((lo[big, None] <= hi[None, big] + gap) & (lo[None, big] <= hi[big, None] + gap), axis=-1)
    a, b = np.nonzero(np.triu(over, 1))
    edges = coo_matrix((np.ones(len(a)), (big[a], big[b])), shape=(k, k))
    _, merged = connected_components(edges, directed=False)
    return np.asarray(merged[lab])


def find_blobs(
    cam: Camera,
    depth: np.ndarray,
    boxes: list[Box3D],
    floor_z: float,
    p: BlobParams,
    labels: tuple[np.ndarray | None, np.ndarray | None] = (None, None),
) -> list[Blob]:
    """The unlabelled blobs of one frame, largest first (see the module docstring). `labels`: per-pixel
    masks of pixels explained by instance labels and of pixels showing an unannotated labelled instance."""
    us, vs, P = _lift(cam, depth)
    keep = P[:, 2] > floor_z + p.floor_band
    in_box = np.zeros(len(P), bool)
    for b in boxes:
        in_box |= b.contains(P, p.box_pad)
    known, other = labels
    if other is not None:
        in_box &= ~other[vs, us]
    keep &= ~in_box
    if known is not None:
        keep &= ~known[vs, us]
    idx = np.flatnonzero(keep)
    if len(idx) == 0:
        return []
    rest, _ = drop_planes(P[idx], p.plane_extent, np.asarray(cam.position, float))
    idx = idx[rest]
    if len(idx) == 0:
        return []
    lab = _clusters(P[idx], p.link)
    min_px = p.min_area * cam.width * cam.height / STRIDE**2
    out = []
    counts = np.bincount(lab)
    for c in np.argsort(-counts, kind="stable"):
        if counts[c] < min_px:
            break
        sel = idx[lab == c]
        Q = P[sel]
        lo, hi = np.percentile(Q, 2, axis=0), np.percentile(Q, 98, axis=0)
        if float(np.max(hi - lo)) < p.min_extent:
            continue
        mask = np.zeros((cam.height, cam.width), bool)
        for dv in range(STRIDE):
            for du in range(STRIDE):
                mask[np.minimum(vs[sel] + dv, cam.height - 1), np.minimum(us[sel] + du, cam.width - 1)] = True
        size = np.maximum(hi - lo, 0.02)
        out.append(Blob(mask, Box3D((lo + hi) / 2.0, size, np.eye(3)), int(mask.sum())))
    return out


def could_be(blob: Blob, category: str, floor_z: float) -> bool:
    """Whether a person could take the blob for a `category`, by the category's plausible size
    (truth/data/category_sizes.yaml): its seen extent lies within the category's extent range (at least
    SEEN_SHARE of the smallest: a seen part much smaller than the smallest such thing is not recognised as
    one), and for things that stand on the floor (a height range starting at FLOOR_THING m or more) its top
    is no higher above the floor than the tallest such thing. Categories without a range could be anything."""
    from refspatial_gen.truth.sizes import size_range

    r = size_range(category)
    if r is None:
        return True
    ext = float(np.max(blob.box.size))
    if not SEEN_SHARE * r.extent[0] <= ext <= r.extent[1]:
        return False
    top = float(blob.box.center[2] + blob.box.size[2] / 2.0) - floor_z
    return r.height is None or r.height[0] < FLOOR_THING or top <= r.height[1]


def stand_ins(blobs: list[Blob], categories: list[str], floor_z: float) -> list[ObjectInstance]:
    """One faint stand-in object per (blob, category it could be), ids from STAND_IN_ID."""
    out = []
    for k, bl in enumerate(blobs):
        ys, xs = np.nonzero(bl.mask)
        bbox = (float(xs.min()), float(ys.min()), float(xs.max() + 1), float(ys.max() + 1))
        rle = RLE.encode(bl.mask)
        for cat in sorted(set(categories)):
            if not could_be(bl, cat, floor_z):
                continue
            prov: dict[str, Any] = {"source": "scan", "distractor_only": "unlabelled_blob", "blob": k}
            prov["blob_pixels"] = bl.pixels
            out.append(
                ObjectInstance(
                    id=0,  # numbered by add_stand_ins
                    category=cat,
                    box=bl.box,
                    mask=rle,
                    bbox2d=bbox,
                    visible_fraction=0.0,
                    provenance=prov,
                )
            )
    return out


CONFIG_KEYS = {  # source config key -> BlobParams field
    "unlabelled_min_area": "min_area",
    "unlabelled_min_extent": "min_extent",
    "unlabelled_box_pad": "box_pad",
    "unlabelled_plane_extent": "plane_extent",
    "unlabelled_link": "link",
}


def params_from(config: dict[str, Any]) -> BlobParams:
    """BlobParams from a scan source config (missing keys: the defaults)."""
    vals = {f: float(config[k]) for k, f in CONFIG_KEYS.items() if config.get(k) is not None}
    return BlobParams(**vals)


def explained_pixels(label_map: np.ndarray | None, known: set[int]) -> tuple[np.ndarray | None, np.ndarray | None]:
    """With per-pixel instance labels: (pixels showing an annotated or structural instance, pixels showing
    another labelled instance: unexplained even inside a box, the chair pushed under a desk)."""
    if label_map is None:
        return None, None
    mine = np.isin(label_map, np.array(sorted(known), np.int64))
    return mine, (label_map > 0) & ~mine


def add_stand_ins(
    objects: list[ObjectInstance],
    cam: Camera,
    depth: np.ndarray,
    boxes: list[Box3D],
    floor_z: float | None,
    config: dict[str, Any],
    labels: tuple[np.ndarray | None, np.ndarray | None] = (None, None),
) -> tuple[list[ObjectInstance], dict[str, int]]:
    """The frame's objects plus faint stand-ins (unlabelled blobs, when the floor is known, and what an
    unreliable label's mask may show), and the counts for meta["truth"]. Stand-ins only take categories
    the frame's named objects have: nothing else can be named in a question."""
    named = sorted({o.category for o in objects if not o.provenance.get("distractor_only")})
    extra = label_stand_ins(objects, named)
    counts: dict[str, int] = {"unreliable_label_stand_ins": len(extra)} if extra else {}
    if floor_z is not None:
        blobs = find_blobs(cam, depth, boxes, floor_z, params_from(config), labels)
        if blobs:
            more = stand_ins(blobs, named, floor_z)
            extra += more
            counts |= {"unlabelled_blobs": len(blobs), "unlabelled_stand_ins": len(more)}
    top = max((o.id for o in objects), default=0)
    base = STAND_IN_ID * (1 + top // STAND_IN_ID)
    for n, o in enumerate(extra):
        o.id = base + n
    return objects + extra, counts


def label_stand_ins(objects: list[ObjectInstance], named: list[str]) -> list[ObjectInstance]:
    """Per object with an unreliable label (truth/labels.py), a faint copy under each category its mask
    may show that the frame also names ("dresser mirror" -> "dresser": the box holds a dresser too)."""
    out = []
    for o in objects:
        for cat in o.provenance.get("label_could_be") or ():
            if cat in named and cat != o.category:
                prov = {"source": "scan", "distractor_only": "unreliable_label", "stand_in_for": int(o.id)}
                out.append(ObjectInstance(0, cat, o.box, o.mask, o.bbox2d, 0.0, provenance=prov))
    return out
