"""`geometric` depth: no weights, only a camera prior. Each object stands where it meets the ground.

The approximation, stated plainly:
- the camera is `camera_height` metres above a flat ground plane, pitched down by `pitch_deg`, no roll;
- an object's contact point is the bottom-centre of its mask; if the pixel just below it belongs to an
  object already placed, the object rests on (or in front of) that object and takes its depth there,
  otherwise the contact ray is intersected with the ground plane;
- every object is a vertical plane parallel to the image plane's horizontal axis ("billboard") through
  its contact point, so all its pixels share that forward distance. Thickness is left to the lifting step;
- objects whose contact lies above the horizon with nothing under them (a kite, a wall clock) cannot be
  placed and are reported as `no_ground_contact`; contacts beyond `max_depth` as `too_far`;
- an object placed so far that it would be over `max_size_ratio` times its category's typical height
  (depth.size_prior) was placed by a wrong contact and is reported as `size_prior_conflict`;
- pixels outside objects are unknown (0), except pixels the annotation says are ground (panoptic
  floor/road/grass stuff), which get the ground plane's depth.
Errors grow with distance and with any deviation from the prior (a photo taken looking down at a table,
an object whose bottom is occluded). Metric relations from this depth are as good as that prior.
"""

from __future__ import annotations

import numpy as np

from refspatial_gen.depth import CameraPrior, DepthResult
from refspatial_gen.depth.size_prior import typical_height
from refspatial_gen.schema import Field

EPS = 1e-6


class GeometricDepth:
    name = "geometric"
    OPTIONS = {
        "camera_height": Field(float, default=1.5, min=0.05, doc="camera height above the ground (m)"),
        "pitch_deg": Field(float, default=0.0, min=-60.0, doc="downward camera pitch (degrees)"),
        "max_depth": Field(float, default=60.0, min=1.0, doc="objects placed farther are dropped (m)"),
        "support": Field(bool, default=True, doc="objects may rest on objects below them in the image"),
        "max_size_ratio": Field(float, default=3.0, min=1.0,
                                doc="drop objects placed so far that they would be this many times taller "
                                    "than their category's typical height (0 = no check)"),
        "size_fallback": Field(bool, default=True,
                               doc="place objects without a usable contact by their category's typical height "
                                   "(only when the mask does not touch the image border)"),
    }

    def __init__(self, camera_height: float = 1.5, pitch_deg: float = 0.0, max_depth: float = 60.0,
                 support: bool = True, max_size_ratio: float = 3.0, size_fallback: bool = True) -> None:
        self.camera_height, self.pitch, self.max_depth, self.support = camera_height, np.deg2rad(pitch_deg), max_depth, support
        self.max_size_ratio, self.size_fallback = max_size_ratio, size_fallback

    def _prior(self, prior: CameraPrior) -> tuple[float, float]:
        h = prior.camera_height if prior.camera_height is not None else self.camera_height
        p = prior.pitch if prior.pitch is not None else self.pitch
        return float(h), float(p)

    def _size_depth(self, ys: np.ndarray, xs: np.ndarray, shape: tuple[int, int], typical: float | None,
                    P: CameraPrior) -> float | None:
        """Distance at which the mask's height matches the category's typical height (fronto-parallel)."""
        if not self.size_fallback or not typical:
            return None
        H, W = shape
        if ys.min() == 0 or xs.min() == 0 or ys.max() == H - 1 or xs.max() == W - 1:
            return None  # cut by the border: the visible height is not the object's height
        z = typical * P.fy / float(ys.max() - ys.min() + 1)
        return z if z <= self.max_depth else None

    def estimate(self, rgb: np.ndarray, prior: CameraPrior) -> DepthResult:
        h, pitch = self._prior(prior)
        P = CameraPrior(prior.width, prior.height, prior.fx, prior.fy, prior.cx, prior.cy, h, pitch, prior.roll)
        up = P.up_cam()
        fwd = np.array([0.0, 0.0, 1.0]) - up[2] * up  # optical axis made horizontal
        fwd = fwd / np.linalg.norm(fwd)
        H, W = prior.height, prior.width
        depth = np.zeros((H, W), np.float32)
        owner = np.zeros((H, W), np.int64)  # object id whose billboard is visible at each pixel (0 = none)
        planes: dict[int, tuple[np.ndarray, float]] = {}  # id -> (horizontal unit normal n, offset n.P)
        notes: dict[int, dict] = {}
        masks = [(int(i), np.asarray(m, bool)) for i, m in prior.masks]
        info = {}
        for oid, m in masks:
            ys, xs = np.nonzero(m)
            if ys.size == 0:
                notes[oid] = {"contact": "none", "reason": "empty_mask"}
                continue
            vb = int(ys.max())
            low = ys >= vb - 2
            u = float(np.median(xs[low])) + 0.5  # continuous coordinate of the contact column's centre
            info[oid] = (vb, u, m, ys, xs)
        order = sorted(info, key=lambda i: (-info[i][0], i))  # lowest in the image first
        pending = list(order)
        progress = True
        while pending and progress:
            progress = False
            for oid in list(pending):
                vb, u, m, mys, mxs = info[oid]
                v = vb + 1.0  # the lower edge of the mask's lowest pixel row
                ray = np.array([(u - P.cx) / P.fx, (v - P.cy) / P.fy, 1.0])
                probe_v, probe_u = min(vb + 2, H - 1), int(min(max(np.floor(u), 0), W - 1))
                below = 0
                if self.support and vb + 2 <= H - 1:
                    for other in order:
                        if other != oid and info[other][2][probe_v, probe_u]:
                            below = other
                            break
                truncated = vb >= H - 1
                if below and below in planes:
                    n, off = planes[below]
                    den = float(ray @ n)
                    if den <= EPS:
                        continue
                    z = off / den
                    contact = f"support:{below}"
                elif below and below in pending:
                    continue  # wait for the object underneath to be placed first
                else:
                    den = float(ray @ up)
                    if den >= -EPS:
                        z = -1.0  # no ground contact: only the size prior can place it
                    else:
                        z = -h / den
                    contact = "ground"
                pending.remove(oid)
                progress = True
                fail = None
                if z < 0:
                    fail = {"reason": "no_ground_contact"}
                elif z > self.max_depth:
                    fail = {"reason": "too_far", "contact_depth": z}
                typical = typical_height(prior.categories.get(oid, ""))
                if fail is None and typical and self.max_size_ratio:
                    implied = (mys.max() - mys.min() + 1) * z / P.fy
                    if implied > self.max_size_ratio * typical:
                        fail = {"reason": "size_prior_conflict", "contact_depth": z, "implied_height": round(float(implied), 3)}
                if fail is not None:
                    zs = self._size_depth(mys, mxs, (H, W), typical, P)
                    if zs is None:
                        notes[oid] = {"contact": "none", "contact_px": [u, v], **fail}
                        continue
                    z, contact, ray = zs, "size_prior", np.array([(u - P.cx) / P.fx, (v - P.cy) / P.fy, 1.0])
                    ray = ray / ray[2]
                Pc = ray * z
                n = fwd  # fronto-parallel billboard: facing the camera's horizontal forward direction
                off = float(n @ Pc)
                planes[oid] = (n, off)
                ys, xs = mys, mxs
                rays = np.stack([(xs + 0.5 - P.cx) / P.fx, (ys + 0.5 - P.cy) / P.fy, np.ones(xs.size)], axis=1)
                den = rays @ n
                zz = np.where(den > EPS, off / np.maximum(den, EPS), 0.0)
                zz = np.where(zz <= self.max_depth, zz, 0.0).astype(np.float32)
                cur = depth[ys, xs]
                take = (zz > 0) & ((cur == 0) | (zz < cur))
                depth[ys[take], xs[take]] = zz[take]
                owner[ys[take], xs[take]] = oid
                notes[oid] = {"contact": contact, "truncated": bool(truncated), "contact_px": [u, v],
                              "contact_depth": float(z)}
        for oid in pending:  # resting on something that could not be placed
            notes[oid] = {"contact": "none", "reason": "no_ground_contact"}
        if prior.ground_mask is not None:
            g = np.asarray(prior.ground_mask, bool) & (owner == 0)
            den = P.rays()[g] @ up
            zz = np.where(den < -EPS, -h / np.minimum(den, -EPS), 0.0)
            zz = np.where(zz <= self.max_depth, zz, 0.0)
            depth[g] = zz.astype(np.float32)
        horizon = P.cy - P.fy * np.tan(pitch)
        meta = {"objects": {str(k): notes[k] for k in sorted(notes)}, "camera_height": h, "pitch": pitch,
                "horizon_row": float(horizon)}
        return DepthResult(depth, True, f"geometric:h={h:.2f},pitch={np.rad2deg(pitch):.1f}deg", meta)
