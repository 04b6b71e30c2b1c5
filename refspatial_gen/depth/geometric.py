"""`geometric` depth: no weights, only a camera prior. Each object stands where it meets the ground.

The approximation, stated plainly:
- the camera is `camera_height` metres above a flat ground plane, pitched down by `pitch_deg`, no roll
  (the image source fits both per photo to the objects of known size first: depth/camera_fit.py);
- an object's contact is the bottom edge of its mask. When another object's mask lies right under that
  edge (over at least `occluded_share` of its width), its foot may be hidden: it either rests on that
  object or stands behind it (occlusion-aware support; see `_on_or_behind`). It rests on it only when
    0. the other object lies under at least `rest_share` of its bottom edge,
    1. the lower object's category can bear it (truth/data/bearing.yaml: a table bears a cup; a car, a
       bus, a person or an umbrella bears nothing),
    2. the contact is visible on the lower object's top surface: that object's mask also rises above
       the contact beside it (a tabletop around a cup), not merely ending at the contact (the roof of a
       car in front of another), and
    3. geometry agrees: standing at the lower object's depth, its height is inside its category's range.
  Otherwise it stands behind: on the ground, farther than the occluder, at the distance where its top
  row puts its top at the category's typical height (`occluded: category_height`), or it is dropped
  (`occluded: drop`, or no usable typical height) with reason `contact_occluded`;
- everything else meets the ground: the contact ray is intersected with the ground plane;
- every object is a vertical plane parallel to the image plane's horizontal axis ("billboard") through
  its contact point, so all its pixels share that forward distance. Thickness is left to the lifting step;
- objects whose contact lies above the horizon with nothing under them (a kite, a wall clock) cannot be
  placed and are reported as `no_ground_contact`; contacts beyond `max_depth` as `too_far`;
- an object placed so that it would be taller than `max_size_ratio` times the top of its category's
  height range was placed by a wrong contact and is reported as `size_prior_conflict` (or placed by its
  typical height with `size_fallback`: per-object forcing, off by default);
- pixels outside objects are unknown (0), except pixels the annotation says are ground (panoptic
  floor/road/grass stuff), which get the ground plane's depth.
Errors grow with distance and with any deviation from the prior. Metric relations from this depth are
as good as that prior; `Frame.meta["metric_scale"]` says how it was fixed.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from refspatial_gen.depth import CameraPrior, DepthResult
from refspatial_gen.schema import Field
from refspatial_gen.truth.sizes import can_bear, size_range

EPS = 1e-6
OCCLUDED_MODES = ("category_height", "drop")


def height_bounds(category: str) -> tuple[float, float, float] | None:
    """(lo, hi, typical) upright height of a category from truth/data (extent when it has no height)."""
    r = size_range(category)
    if r is None:
        return None
    lo, hi = r.height if r.height is not None else r.extent
    typ = r.typical if r.typical is not None else (float(np.sqrt(lo * hi)) if r.height is not None else None)
    return lo, hi, typ


@dataclass
class _Obj:
    oid: int
    mask: np.ndarray
    ys: np.ndarray
    xs: np.ndarray
    vb: int  # lowest row
    u: float  # contact column (continuous)
    category: str

    @property
    def rows(self) -> int:
        return int(self.ys.max() - self.ys.min() + 1)


def object_below(o: _Obj, owner: np.ndarray) -> tuple[int, float]:
    """The object whose mask lies right under `o`'s bottom edge over the most of its columns, and that
    share of the columns ((0, 0.0): none). `owner` is an (H, W) id map of all masks."""
    H = owner.shape[0]
    cols = np.unique(o.xs)
    low = np.full(owner.shape[1], -1)
    np.maximum.at(low, o.xs, o.ys)
    y = low[cols]
    hit = np.zeros(len(cols), np.int64)
    for dy in (2, 1):  # the nearer row wins
        ok = y + dy < H
        k = np.where(ok, owner[np.minimum(y + dy, H - 1), cols], 0)
        k = np.where((k == o.oid), 0, k)
        hit = np.where(k > 0, k, hit)
    hits = {int(k): int(n) for k, n in zip(*np.unique(hit[hit > 0], return_counts=True))}
    if not hits:
        return 0, 0.0
    k = max(sorted(hits), key=lambda i: hits[i])
    return k, hits[k] / len(cols)


def contact_visible_on(o: _Obj, b_mask: np.ndarray, band: float) -> bool:
    """Is `o`'s foot on the visible top surface of the object with mask `b_mask`? That surface shows
    around the foot: `b_mask` has pixels beside `o` (within half its width) in the rows from `o`'s
    bottom up to `band` x its height above it. An occluder's top edge merely ends at the foot."""
    x0, x1 = int(o.xs.min()), int(o.xs.max())
    w = max(2, (x1 - x0 + 1) // 2)
    r = max(2, int(round(band * o.rows)))
    y1 = o.vb - 1  # rows strictly above the foot's last row
    y0 = max(0, o.vb - r)
    if y1 < y0:
        return False
    H, W = b_mask.shape
    left = b_mask[y0 : y1 + 1, max(0, x0 - w) : x0]
    right = b_mask[y0 : y1 + 1, x1 + 1 : min(W, x1 + 1 + w)]
    return bool(left.any() or right.any())


class GeometricDepth:
    name = "geometric"
    OPTIONS = {
        "camera_height": Field(float, default=1.5, min=0.05, doc="camera height above the ground (m)"),
        "pitch_deg": Field(float, default=0.0, min=-60.0, doc="downward camera pitch (degrees)"),
        "max_depth": Field(float, default=60.0, min=1.0, doc="objects placed farther are dropped (m)"),
        "support": Field(bool, default=True, doc="objects may rest on objects below them in the image"),
        "bearing": Field(
            bool,
            default=True,
            doc="an object rests only on one whose category can bear it "
            "(truth/data/bearing.yaml); else it stands behind it",
        ),
        "contact_band": Field(
            float,
            default=0.15,
            min=0.0,
            doc="resting needs the lower object's mask beside the foot, up to this fraction "
            "of the object's height above it (its top surface is visible there)",
        ),
        "rest_share": Field(
            float,
            default=1 / 3,
            min=0.0,
            max=1.0,
            doc="an object may rest on another whose mask lies under this share of its bottom edge",
        ),
        "occluded_share": Field(
            float,
            default=0.1,
            min=0.0,
            max=1.0,
            doc="an object with another's mask under this share of its bottom edge (less than "
            "rest_share) has its foot partly hidden: it stands behind, never on it",
        ),
        "occluded": Field(
            str,
            default="category_height",
            choices=OCCLUDED_MODES,
            doc="an object whose foot is hidden behind another: placed on the ground behind it "
            "by its category's typical height, or dropped (contact_occluded)",
        ),
        "max_size_ratio": Field(
            float,
            default=1.15,
            min=0.0,
            doc="drop objects placed taller than this times the top of their category's height range (0 = no check)",
        ),
        "size_fallback": Field(
            bool,
            default=False,
            doc="place objects without a usable contact by their category's typical height "
            "(per-object forcing; only when the mask does not touch the image border)",
        ),
    }

    def __init__(
        self,
        camera_height: float = 1.5,
        pitch_deg: float = 0.0,
        max_depth: float = 60.0,
        support: bool = True,
        bearing: bool = True,
        contact_band: float = 0.15,
        rest_share: float = 1 / 3,
        occluded_share: float = 0.1,
        occluded: str = "category_height",
        max_size_ratio: float = 1.15,
        size_fallback: bool = False,
    ) -> None:
        self.camera_height, self.pitch, self.max_depth, self.support = (
            camera_height,
            np.deg2rad(pitch_deg),
            max_depth,
            support,
        )
        self.bearing, self.contact_band, self.occluded = bearing, contact_band, occluded
        self.rest_share, self.occluded_share = rest_share, occluded_share
        self.max_size_ratio, self.size_fallback = max_size_ratio, size_fallback

    def _prior(self, prior: CameraPrior) -> tuple[float, float]:
        h = prior.camera_height if prior.camera_height is not None else self.camera_height
        p = prior.pitch if prior.pitch is not None else self.pitch
        return float(h), float(p)

    def _size_depth(self, o: _Obj, shape: tuple[int, int], typical: float | None, P: CameraPrior) -> float | None:
        """Distance at which the mask's height matches the category's typical height (fronto-parallel)."""
        if not self.size_fallback or not typical:
            return None
        H, W = shape
        if o.ys.min() == 0 or o.xs.min() == 0 or o.vb == H - 1 or o.xs.max() == W - 1:
            return None  # cut by the border: the visible height is not the object's height
        z = typical * P.fy / float(o.rows)
        return z if z <= self.max_depth else None

    def _too_tall(self, o: _Obj, z: float, fy: float) -> float | None:
        """The implied visible height when it exceeds `max_size_ratio` x the category's top height."""
        hb = height_bounds(o.category)
        if hb is None or not self.max_size_ratio:
            return None
        implied = o.rows * z / fy
        return implied if implied > self.max_size_ratio * hb[1] else None

    def _behind_depth(
        self, o: _Obj, z_occluder: float, h: float, pitch: float, P: CameraPrior, thickness: float
    ) -> float | None:
        """Horizontal distance of an object standing on the ground behind an occluder: where its top row
        puts its top at its category's typical height, but never nearer than the occluder's back
        (`z_occluder` + `thickness`); the height that distance implies must be inside the category's
        range. None when the category has no typical height, the top row is cut by the border or near
        the horizon, or no distance behind the occluder gives a plausible height."""
        hb = height_bounds(o.category)
        if self.occluded == "drop" or hb is None or hb[2] is None or int(o.ys.min()) == 0:
            return None
        t = np.tan(pitch + np.arctan((float(o.ys.min()) - P.cy) / P.fy))  # the top edge's slope below horizontal
        if abs(t) < 0.02:
            return None
        d_typ = (h - hb[2]) / t
        d = max(d_typ if d_typ > 0 else 0.0, z_occluder + thickness)
        height = h - d * t
        if not (hb[0] / 1.15 <= height <= hb[1] * 1.15):
            return None
        return float(d)

    def _on_or_behind(self, o: _Obj, b: _Obj, z_b: float, P: CameraPrior, share: float) -> str:
        """ "on" when `o` may rest on `b` (enough of its foot on it, bearing, visible contact, plausible
        height), else "behind"."""
        if share < self.rest_share:
            return "behind"
        if self.bearing and not can_bear(b.category, o.category):
            return "behind"
        if not contact_visible_on(o, b.mask, self.contact_band):
            return "behind"
        hb = height_bounds(o.category)
        if hb is not None:
            implied = o.rows * z_b / P.fy
            lo, hi = hb[0] / 1.15, hb[1] * 1.15
            if implied > hi or (implied < lo and int(o.ys.min()) > 0):
                return "behind"
        return "on"

    def estimate(self, rgb: np.ndarray, prior: CameraPrior) -> DepthResult:
        h, pitch = self._prior(prior)
        P = CameraPrior(prior.width, prior.height, prior.fx, prior.fy, prior.cx, prior.cy, h, pitch, prior.roll)
        up = P.up_cam()
        fwd = np.array([0.0, 0.0, 1.0]) - up[2] * up  # optical axis made horizontal
        fwd = fwd / np.linalg.norm(fwd)
        H, W = prior.height, prior.width
        depth = np.zeros((H, W), np.float32)
        owner = np.zeros((H, W), np.int64)  # object id whose billboard is visible at each pixel (0 = none)
        ids = np.zeros((H, W), np.int64)  # object id of each mask pixel (masks are disjoint or first wins)
        planes: dict[int, tuple[np.ndarray, float]] = {}  # id -> (horizontal unit normal n, offset n.P)
        notes: dict[int, dict] = {}
        info: dict[int, _Obj] = {}
        for oid, m in [(int(i), np.asarray(m, bool)) for i, m in prior.masks]:
            ys, xs = np.nonzero(m)
            if ys.size == 0:
                notes[oid] = {"contact": "none", "reason": "empty_mask"}
                continue
            vb = int(ys.max())
            u = float(np.median(xs[ys >= vb - 2])) + 0.5  # continuous coordinate of the contact column's centre
            info[oid] = _Obj(oid, m, ys, xs, vb, u, prior.categories.get(oid, ""))
            ids[m & (ids == 0)] = oid
        below: dict[int, tuple[int, float]] = {}
        for oid, o in info.items():
            k, share = object_below(o, ids) if self.support else (0, 0.0)
            # what bears or hides a foot reaches lower in the picture than that foot (a rider's shoe under
            # the pedal does not hide the bicycle's wheels): the relation is acyclic
            ok = k and share >= min(self.occluded_share, self.rest_share) and info[k].vb > o.vb
            below[oid] = (k, share) if ok else (0, 0.0)
        order = sorted(info, key=lambda i: (-info[i].vb, i))  # lowest in the image first
        pending = list(order)
        progress = True
        while pending and progress:
            progress = False
            for oid in list(pending):
                o = info[oid]
                b, share = below[oid]
                if b and b in pending and b != oid:
                    continue  # wait for the object underneath to be placed first
                pending.remove(oid)
                progress = True
                note = self._place(o, info.get(b), share, planes, notes, P, h, pitch, up, fwd, H)
                if note.get("contact") == "none":
                    notes[oid] = note
                    continue
                n, off = fwd, note.pop("_offset")
                planes[oid] = (n, off)
                rays = np.stack([(o.xs + 0.5 - P.cx) / P.fx, (o.ys + 0.5 - P.cy) / P.fy, np.ones(o.xs.size)], axis=1)
                den = rays @ n
                zz = np.where(den > EPS, off / np.maximum(den, EPS), 0.0)
                zz = np.where(zz <= self.max_depth, zz, 0.0).astype(np.float32)
                cur = depth[o.ys, o.xs]
                take = (zz > 0) & ((cur == 0) | (zz < cur))
                depth[o.ys[take], o.xs[take]] = zz[take]
                owner[o.ys[take], o.xs[take]] = oid
                notes[oid] = note
        for oid in pending:  # resting on something that could not be placed
            notes[oid] = {"contact": "none", "reason": "no_ground_contact"}
        if prior.ground_mask is not None:
            g = np.asarray(prior.ground_mask, bool) & (owner == 0)
            den = P.rays()[g] @ up
            zz = np.where(den < -EPS, -h / np.minimum(den, -EPS), 0.0)
            zz = np.where(zz <= self.max_depth, zz, 0.0)
            depth[g] = zz.astype(np.float32)
        horizon = P.cy - P.fy * np.tan(pitch)
        meta = {
            "objects": {str(k): notes[k] for k in sorted(notes)},
            "camera_height": h,
            "pitch": pitch,
            "horizon_row": float(horizon),
        }
        return DepthResult(depth, True, f"geometric:h={h:.2f},pitch={np.rad2deg(pitch):.1f}deg", meta)

    def _place(
        self,
        o: _Obj,
        b: _Obj | None,
        share: float,
        planes: dict,
        notes: dict,
        P: CameraPrior,
        h: float,
        pitch: float,
        up: np.ndarray,
        fwd: np.ndarray,
        H: int,
    ) -> dict:
        """Contact note of one object: {"contact", "_offset" (billboard n.P), ...} or {"contact": "none", "reason"}."""
        v = o.vb + 1.0  # the lower edge of the mask's lowest pixel row
        ray = np.array([(o.u - P.cx) / P.fx, (v - P.cy) / P.fy, 1.0])
        truncated = o.vb >= H - 1
        base = {"truncated": bool(truncated), "contact_px": [o.u, v]}
        z, contact, fail = -1.0, "ground", None
        if b is not None and b.oid in planes:
            n_b, off_b = planes[b.oid]
            z_b = off_b  # the billboard's forward distance
            way = self._on_or_behind(o, b, z_b, P, share)
            if way == "on":
                den = float(ray @ n_b)
                z = off_b / den if den > EPS else -1.0
                contact = f"support:{b.oid}"
            else:
                thickness = min(b.rows, int(b.xs.max() - b.xs.min() + 1)) * z_b / P.fy
                d = self._behind_depth(o, z_b, h, pitch, P, thickness)
                if d is None:
                    return {"contact": "none", "reason": "contact_occluded", "occluder": b.oid, **base}
                return {
                    "contact": f"behind:{b.oid}",
                    "_offset": d,
                    "contact_depth": d,
                    "depth_from": "category_height",
                    **base,
                }
        elif b is not None:  # the object under it could not be placed: neither can this one be
            return {"contact": "none", "reason": "no_ground_contact", **base}
        else:
            den = float(ray @ up)
            z = -h / den if den < -EPS else -1.0
        if z < 0:
            fail = {"reason": "no_ground_contact"}
        elif z > self.max_depth:
            fail = {"reason": "too_far", "contact_depth": z}
        else:
            implied = self._too_tall(o, z, P.fy)
            if implied is not None:
                fail = {"reason": "size_prior_conflict", "contact_depth": z, "implied_height": round(float(implied), 3)}
        if fail is not None:
            hb = height_bounds(o.category)
            zs = self._size_depth(o, (H, P.width), hb[2] if hb else None, P)
            if zs is None:
                return {"contact": "none", **base, **fail}
            z, contact, ray = zs, "size_prior", ray / ray[2]
        Pc = ray * z
        return {"contact": contact, "_offset": float(fwd @ Pc), "contact_depth": float(z), **base}
