"""Visible masks for box-only annotations, from a metric depth map: depth layering of overlapping boxes.

A 2D box holds its object plus whatever is seen around it: the floor and wall behind, and nearer objects
in front (a night stand whose box is mostly the bed before it). Picking the nearest or the largest
depth cluster inside the box fails exactly there. Instead the whole image is cut into segments:
- the inliers of each background plane (floor, support planes, walls) form their own segments, one per
  blob (connected through pixels without depth), so a wall splits from the headboard in front of it;
- the other pixels are cut at depth jumps (the same rule as lifting: a neighbour jump of more than
  max(5 cm, 3% of depth)); small holes are bridged and pixels on a jump join the side they match.
A segment is given to boxes only when most of it (`min_share`) lies inside the boxes and at least
`min_single` inside one of them: a segment that runs out of the boxes (the wall, the floor) is nobody's.
Each pixel is private to the smallest box holding it. A box whose private part holds a real share
(`min_exclusive`) of the segment claims it: one claimant takes it (a bed passing in front of a night
stand is a sliver of the bed, so only the bed claims it); several claimants split it, overlap pixels
going to the box whose own part is at their depth (the nearer box takes the near layer: a bench
touching the footboard behind it); no claimant (wholly inside nested boxes) -> the smallest box holding
it (a lamp inside the box of the bed behind it). So a plane blob is only background when it extends
beyond the boxes, and a surface inside one box stays with its object.
Each box then keeps its best segment (weighted towards the box centre) plus the other segments it owns
that touch them in the image, lie within max(`join_gap`, `join_rel` x the main part's width) in 3D and
do not make the 3D extent project more than `max_spill` beyond the 2D box (the 3D box of an object
projects onto its 2D box: a mirror's reflections and the room corner behind do not), and the isolated
pixels of its private area at the object's depth.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Any

import numpy as np

from refspatial_gen.sources.image.lift import depth_components


@dataclass
class BoxMasks:
    """Per box: bool (H, W) mask of the pixels chosen for it (disjoint across boxes) and notes."""

    masks: list[np.ndarray]
    notes: list[dict] = field(default_factory=list)
    labels: np.ndarray | None = None  # (H, W) segment labels, 0 = no depth / depth edge


def plane_labels(
    world: np.ndarray, valid: np.ndarray, support_z: list[float], walls: list[tuple[np.ndarray, float]], band: float
) -> np.ndarray:
    """(H, W) int: k+1 where the pixel lies within `band` of plane k (horizontal planes, then walls)."""
    out = np.zeros(valid.shape, np.int32)
    k = 0
    for z in support_z:
        k += 1
        out[(out == 0) & valid & (np.abs(world[..., 2] - z) < band)] = k
    for n, d in walls:
        k += 1
        out[(out == 0) & valid & (np.abs(world @ n + d) < band)] = k
    return out


def fill_small_holes(depth: np.ndarray, size: int = 5) -> np.ndarray:
    """Missing pixels take the nearest depth within a `size` window (only for cutting segments: sparse
    depth on thin or shiny objects would otherwise fall apart into specks)."""
    import cv2

    d = np.where(depth > 0, depth, np.inf).astype(np.float32)
    near = cv2.erode(d, np.ones((size, size), np.uint8), borderType=cv2.BORDER_REPLICATE)
    return np.where(depth > 0, depth, np.where(np.isfinite(near), near, 0.0)).astype(np.float32)


def _attach_edges(
    lab: np.ndarray, depth: np.ndarray, rel_jump: float = 0.03, abs_jump: float = 0.05, rounds: int = 2
) -> np.ndarray:
    """Pixels on a depth jump (label 0 with depth) join the neighbouring segment whose depth they match:
    the jump lies between two surfaces, and each side's pixels belong to that side (a thin lamp stem
    against a far wall is mostly such pixels)."""
    lab = lab.copy()
    H, W = lab.shape
    for _ in range(rounds):
        todo = (lab == 0) & (depth > 0)
        if not todo.any():
            break
        best = np.full((H, W), np.inf, np.float32)
        new = np.zeros_like(lab)
        for dy, dx in ((0, 1), (0, -1), (1, 0), (-1, 0)):
            nl = np.zeros_like(lab)
            nd = np.zeros_like(depth, dtype=np.float32)
            ys = slice(max(dy, 0), H + min(dy, 0))
            yd = slice(max(-dy, 0), H + min(-dy, 0))
            xs = slice(max(dx, 0), W + min(dx, 0))
            xd = slice(max(-dx, 0), W + min(-dx, 0))
            nl[yd, xd] = lab[ys, xs]
            nd[yd, xd] = depth[ys, xs]
            diff = np.abs(depth - nd).astype(np.float32)
            ok = todo & (nl > 0) & (diff <= np.maximum(abs_jump, rel_jump * depth)) & (diff < best)
            best[ok] = diff[ok]
            new[ok] = nl[ok]
        lab[new > 0] = new[new > 0]
    return lab


def segment_image(depth: np.ndarray, planes: np.ndarray) -> np.ndarray:
    """Segments (labels >= 1) of the valid pixels: blobs of each plane's inliers (connected through
    pixels without depth), and depth-continuous regions of the rest (small holes bridged). Pixels
    without depth or on a depth jump get 0."""
    import cv2

    rest = np.where(planes == 0, fill_small_holes(np.where(planes == 0, depth, 0.0)), 0.0).astype(np.float32)
    lab = depth_components(rest).astype(np.int32)
    lab[depth <= 0] = 0
    lab = _attach_edges(lab, np.where(planes == 0, depth, 0.0))
    nxt = int(lab.max()) + 1
    for k in range(1, int(planes.max()) + 1):
        m = planes == k
        if not m.any():
            continue
        # pixels without depth bridge the blob (a noisy wall seen around a lamp shade is one wall)
        n, pl = cv2.connectedComponents((m | (depth <= 0)).astype(np.uint8), connectivity=8)
        lab[m] = pl[m] + nxt - 1
        nxt += n - 1
    return lab


def _pixel_rect(bb: tuple[float, float, float, float], W: int, H: int) -> tuple[int, int, int, int]:
    x0, y0, x1, y1 = bb
    return (max(0, int(np.floor(x0))), max(0, int(np.floor(y0))), min(W, int(np.ceil(x1))), min(H, int(np.ceil(y1))))


def _owner_map(
    lab: np.ndarray,
    depth: np.ndarray,
    rects: list[tuple[int, int, int, int]],
    min_share: float,
    min_single: float,
    tie: float,
    min_exclusive: float,
    min_segment: int,
) -> np.ndarray:
    """(H, W) int: the box each pixel is given to (-1: none). See the module docstring."""
    H, W = lab.shape
    nb, nseg = len(rects), int(lab.max()) + 1
    owner = np.full((H, W), -1, np.int32)
    if nb == 0 or nseg <= 1:
        return owner
    total = np.maximum(np.bincount(lab.ravel(), minlength=nseg).astype(np.float64), 1.0)
    inb = np.zeros((nb, H, W), bool)
    for i, (x0, y0, x1, y1) in enumerate(rects):
        inb[i, y0:y1, x0:x1] = True
    area = inb.reshape(nb, -1).sum(axis=1)
    # each pixel is private to the smallest box holding it (a lamp's box inside the bed's box is the lamp's)
    inner = np.full((H, W), -1, np.int32)
    for i in np.argsort(-area, kind="stable"):
        inner[inb[i]] = i
    priv = np.stack([inner == i for i in range(nb)])
    inside = np.stack([np.bincount(lab[inb[i]], minlength=nseg) for i in range(nb)]).astype(np.float64)
    excl = np.stack([np.bincount(lab[priv[i]], minlength=nseg) for i in range(nb)]).astype(np.float64)
    share = inside / total
    share[:, 0] = 0.0
    best = share.max(axis=0)
    in_any = np.bincount(lab[inner >= 0], minlength=nseg) / total
    seg_box = np.full(nseg, -1, np.int64)  # segments given whole to one box
    split: list[tuple[int, np.ndarray]] = []  # segments shared by several claimant boxes
    for s in np.flatnonzero((best >= min_single) & (in_any >= min_share)):
        if s == 0:
            continue
        # a box claims the segment when its private part is a real share of the segment (a bed passing in
        # front of a night stand is a sliver of the bed: the night stand does not claim it)
        claim = np.flatnonzero((excl[:, s] >= min_exclusive * total[s]) & (excl[:, s] >= min_segment))
        if claim.size == 1:
            seg_box[s] = int(claim[0])
        elif claim.size == 0:  # wholly inside overlaps of boxes: the smallest box holding (nearly) all of it
            cand = np.flatnonzero(share[:, s] >= best[s] - tie)
            seg_box[s] = int(cand[np.argmin(area[cand])])
        else:
            split.append((int(s), claim))
    ys, xs = np.nonzero(lab > 0)
    b = seg_box[lab[ys, xs]]
    ok = b >= 0
    ok[ok] = inb[b[ok], ys[ok], xs[ok]]
    owner[ys[ok], xs[ok]] = b[ok]
    for s, claim in split:
        # one surface running through several boxes (a bench against the bed's footboard): each box takes
        # its own part, and where boxes overlap the pixel goes to the box whose own part is at its depth
        sy, sx = np.nonzero(lab == s)
        ref = np.array([np.median(depth[sy, sx][priv[c, sy, sx]]) for c in claim])
        held = inb[claim][:, sy, sx]  # (claimants, pixels)
        dz = np.abs(depth[sy, sx][None, :] - ref[:, None])
        dz[~held] = np.inf
        k = np.argmin(dz, axis=0)
        fine = np.isfinite(dz[k, np.arange(len(k))])
        owner[sy[fine], sx[fine]] = claim[k[fine]]
    return owner


def _spill(lo: np.ndarray, hi: np.ndarray, bb: tuple[float, float, float, float], cam) -> float:
    """How far the projection of the world box [lo, hi] reaches beyond the 2D box `bb` (inside the image),
    as a fraction of the 2D box's width or height: the 3D box of an object must project onto its 2D box."""
    corners = np.array([[x, y, z] for x in (lo[0], hi[0]) for y in (lo[1], hi[1]) for z in (lo[2], hi[2])])
    uv, zc = cam.project(corners)
    if not np.all(np.isfinite(uv)) or np.any(zc <= 0):
        return np.inf
    u = np.clip(uv[:, 0], 0, cam.width)
    v = np.clip(uv[:, 1], 0, cam.height)
    x0, y0, x1, y1 = bb
    bw, bh = max(x1 - x0, 1.0), max(y1 - y0, 1.0)
    return float(max(0.0, (x0 - u.min()) / bw, (u.max() - x1) / bw, (y0 - v.min()) / bh, (v.max() - y1) / bh))


def assign_boxes(
    depth: np.ndarray,
    world: np.ndarray,
    boxes: list[tuple[float, float, float, float]],
    support_z: list[float],
    walls: list[tuple[np.ndarray, float]],
    band: float = 0.03,
    min_share: float = 0.8,
    min_single: float = 0.5,
    tie: float = 0.05,
    min_exclusive: float = 0.1,
    join_gap: float = 0.25,
    join_rel: float = 0.5,
    join_px: int = 4,
    min_segment: int = 20,
    cam=None,
    max_spill: float = 0.15,
) -> BoxMasks:
    """Masks for box annotations `boxes` (x0, y0, x1, y1 continuous pixels) over a metric `depth`
    (0 = none) whose world points (z up) are `world` (H, W, 3). See the module docstring."""
    H, W = depth.shape
    valid = depth > 0
    planes = plane_labels(world, valid, support_z, walls, band)
    lab = segment_image(depth, planes)
    rects = [_pixel_rect(b, W, H) for b in boxes]
    owner = _owner_map(lab, depth, rects, min_share, min_single, tie, min_exclusive, min_segment)
    inner = np.full((H, W), -1, np.int32)  # the smallest box holding each pixel
    for i in np.argsort([-(x1 - x0) * (y1 - y0) for x0, y0, x1, y1 in rects], kind="stable"):
        x0, y0, x1, y1 = rects[i]
        inner[y0:y1, x0:x1] = i
    # isolated pixels (label 0 with depth, off every plane): speckled depth on thin or shiny objects
    loose = (lab == 0) & valid & (planes == 0)
    join = _Join(join_gap, join_rel, join_px, min_segment, cam, max_spill)
    masks, notes = [], []
    for i, rect in enumerate(rects):
        m, note = _box_mask(i, rect, boxes[i], lab, owner, inner, loose, depth, world, join)
        masks.append(m)
        notes.append(note)
    return BoxMasks(masks, notes, lab)


@dataclass(frozen=True)
class _Join:
    """When an owned segment joins a box's main segment (see the module docstring)."""

    gap: float
    rel: float
    px: int
    min_segment: int
    cam: Any
    max_spill: float


def _box_mask(
    i: int,
    rect: tuple[int, int, int, int],
    bb: tuple[float, float, float, float],
    lab: np.ndarray,
    owner: np.ndarray,
    inner: np.ndarray,
    loose: np.ndarray,
    depth: np.ndarray,
    world: np.ndarray,
    join: _Join,
) -> tuple[np.ndarray, dict]:
    """Box i's mask: its best owned segment (weighted towards the box centre), the owned segments that join
    it, and the isolated pixels of its private area at the object's depth; and its notes."""
    H, W = depth.shape
    x0, y0, x1, y1 = rect
    sub = np.where(owner[y0:y1, x0:x1] == i, lab[y0:y1, x0:x1], 0)
    ys, xs = np.mgrid[y0:y1, x0:x1]
    bx0, by0, bx1, by1 = bb
    cx, cy, hw, hh = (bx0 + bx1) / 2, (by0 + by1) / 2, (bx1 - bx0) / 4, (by1 - by0) / 4
    w = np.where((np.abs(xs + 0.5 - cx) <= hw) & (np.abs(ys + 0.5 - cy) <= hh), 1.0, 0.2)
    segs, inv = np.unique(sub, return_inverse=True)
    inv = inv.reshape(sub.shape)
    score = np.bincount(inv.ravel(), weights=w.ravel(), minlength=len(segs))
    count = np.bincount(inv.ravel(), minlength=len(segs))
    keep = (segs > 0) & (count >= 3)
    note: dict = {"owned_segments": int(keep.sum())}
    if not keep.any():
        return np.zeros((H, W), bool), note
    cand = np.flatnonzero(keep)
    cand = cand[np.argsort(-score[cand], kind="stable")]
    pts = world[y0:y1, x0:x1].reshape(-1, 3)
    flat = inv.ravel()
    order = np.argsort(flat, kind="stable")
    starts = np.searchsorted(flat[order], np.arange(len(segs) + 1))
    big = [int(cand[0])] + [int(k) for k in cand[1:] if count[k] >= join.min_segment]
    ext = {}
    for k in big:  # robust 3D extents of the main segment and of those big enough to join
        p = pts[order[starts[k] : starts[k + 1]]]
        ext[k] = (np.percentile(p, 2, axis=0), np.percentile(p, 98, axis=0))
    chosen = _join_segments(big, ext, inv, bb, join)
    m = np.zeros((H, W), bool)
    m[y0:y1, x0:x1] = np.isin(inv, chosen) & (sub > 0)
    # isolated pixels at the object's depth, in the part of the box no smaller box covers
    zc = depth[y0:y1, x0:x1]
    zmed = float(np.median(zc[m[y0:y1, x0:x1]]))
    add = loose[y0:y1, x0:x1] & (inner[y0:y1, x0:x1] == i) & (np.abs(zc - zmed) <= max(0.05, 0.03 * zmed))
    m[y0:y1, x0:x1] |= add
    note["segments"] = len(chosen)
    note["isolated_pixels"] = int(add.sum())
    return m, note


def _join_segments(
    big: list[int],
    ext: dict[int, tuple[np.ndarray, np.ndarray]],
    inv: np.ndarray,
    bb: tuple[float, float, float, float],
    join: _Join,
) -> list[int]:
    """The best segment `big[0]`, then (transitively) every other one that touches the chosen ones in the
    image, lies near them in 3D and keeps the 3D extent on the 2D box `bb`."""
    import cv2

    chosen = [big[0]]
    lo, hi = ext[chosen[0]]
    # parts of one object lie within a fraction of its size of each other (the main part's size: a
    # limit that grew with the union would let it run away through clutter)
    limit = max(join.gap, join.rel * float(np.max(hi[:2] - lo[:2])))
    rest = big[1:]
    kern = np.ones((2 * join.px + 1, 2 * join.px + 1), np.uint8)
    cam = join.cam
    grew = True
    while grew and rest:
        grew = False
        near = cv2.dilate(np.isin(inv, chosen).astype(np.uint8), kern) > 0
        for k in list(rest):
            slo, shi = ext[k]
            gap = np.maximum(0.0, np.maximum(slo - hi, lo - shi))
            if float(np.linalg.norm(gap)) > limit or not bool(np.any(near & (inv == k))):
                continue
            if cam is not None and _spill(np.minimum(lo, slo), np.maximum(hi, shi), bb, cam) > max(
                join.max_spill, _spill(lo, hi, bb, cam)
            ):
                continue
            chosen.append(k)
            rest.remove(k)
            lo, hi = np.minimum(lo, slo), np.maximum(hi, shi)
            grew = True
    return chosen
