"""Scale recovery for depth models that predict relative depth or relative inverse depth (disparity).

Relative Depth Anything predicts affine-invariant disparity: disp = a / z + b with unknown a, b.
Methods (chosen in the recipe, all stated in the result's `origin`):
- `contacts`: anchors from the geometric prior (objects' ground contacts under the camera height/pitch
  prior); fit 1/z = alpha * disp + beta by least squares with >= 3 anchors, scale only with 1-2;
- `camera_height`: treat 1/disp as depth up to scale, find the floor by RANSAC (normal near the prior up)
  and scale so the camera sits `camera_height` above it;
- `median`: scale so the median valid depth equals `median_depth` (a crude last resort);
- `none`: keep relative (the image source drops such frames: metric relations would be meaningless).
Failure raises DropUnit("depth_scale_unrecoverable") rather than guessing.
"""

from __future__ import annotations

import numpy as np

from refspatial_gen.core.errors import DropUnit
from refspatial_gen.depth import CameraPrior
from refspatial_gen.depth.planes import ransac_plane

METHODS = ("contacts", "camera_height", "median", "none")


def _to_relative_depth(pred: np.ndarray, kind: str) -> np.ndarray:
    p = np.asarray(pred, np.float64)
    if kind == "disparity":
        pos = p > 1e-6 * max(float(np.nanmax(p)), 1e-12)
        z = np.where(pos, 1.0 / np.where(pos, p, 1.0), 0.0)
    else:
        z = np.where(p > 0, p, 0.0)
    return np.where(np.isfinite(z), z, 0.0)


def contact_anchors(prior: CameraPrior, camera_height: float, pitch: float) -> list[tuple[int, int, float]]:
    """(u, v, metric z) of objects' ground contacts under the geometric prior."""
    from refspatial_gen.depth.geometric import GeometricDepth

    if not prior.masks:
        return []
    g = GeometricDepth(camera_height=camera_height, pitch_deg=float(np.rad2deg(pitch)), support=False)
    res = g.estimate(np.zeros((prior.height, prior.width, 3), np.uint8), prior)
    out = []
    for _k, note in sorted(res.meta["objects"].items(), key=lambda kv: int(kv[0])):
        if note.get("contact") == "ground" and not note.get("truncated"):
            u, v = note["contact_px"]
            # continuous contact (lower edge of the lowest row) -> that row's pixel index
            out.append(
                (
                    int(min(prior.width - 1, np.floor(u))),
                    int(min(prior.height - 1, np.ceil(v) - 1)),
                    float(note["contact_depth"]),
                )
            )
    return out


def _sample(pred: np.ndarray, u: int, v: int, r: int = 2) -> float:
    patch = pred[max(v - r, 0) : v + 1, max(u - r, 0) : u + r + 1]
    vals = patch[np.isfinite(patch) & (patch > 0)]
    return float(np.median(vals)) if vals.size else 0.0


def recover_metric(
    pred: np.ndarray,
    kind: str,
    prior: CameraPrior,
    method: str,
    camera_height: float,
    pitch: float,
    median_depth: float | None,
    rng: np.random.Generator,
) -> tuple[np.ndarray, str, dict]:
    """Relative prediction (`kind` "disparity" or "depth") -> (metric depth float32, origin, meta)."""
    if method == "none":
        return _to_relative_depth(pred, kind).astype(np.float32), "relative", {}
    if method == "contacts":
        anchors = contact_anchors(prior, camera_height, pitch)
        samples = [(_sample(pred, u, v), z) for u, v, z in anchors]
        samples = [(p, z) for p, z in samples if p > 0]
        if not samples:
            raise DropUnit("depth_scale_unrecoverable", "no object meets the ground below the horizon")
        p = np.array([s[0] for s in samples])
        z = np.array([s[1] for s in samples])
        if kind == "disparity":
            inv = 1.0 / z
            alpha, beta = float(np.median(inv / p)), 0.0
            if len(samples) >= 3 and np.ptp(p) > 1e-6:
                A = np.stack([p, np.ones_like(p)], axis=1)
                (a2, b2), *_ = np.linalg.lstsq(A, inv, rcond=None)
                if a2 > 0:
                    alpha, beta = float(a2), float(b2)
            with np.errstate(divide="ignore", invalid="ignore"):
                invz = alpha * np.asarray(pred, np.float64) + beta
                depth = np.where(invz > 1e-6, 1.0 / invz, 0.0)
            meta = {"alpha": alpha, "beta": beta, "anchors": len(samples)}
        else:
            s = float(np.median(z / p))
            depth = np.asarray(pred, np.float64) * s
            meta = {"scale": s, "anchors": len(samples)}
        return np.where(np.isfinite(depth) & (depth > 0), depth, 0.0).astype(np.float32), "scale:contacts", meta
    rel = _to_relative_depth(pred, kind)
    if method == "median":
        if not median_depth:
            raise DropUnit("depth_scale_unrecoverable", "scale_recovery median needs median_depth")
        med = float(np.median(rel[rel > 0])) if np.any(rel > 0) else 0.0
        if med <= 0:
            raise DropUnit("depth_scale_unrecoverable", "prediction has no positive depth")
        s = median_depth / med
        return (rel * s).astype(np.float32), "scale:median", {"scale": s}
    if method == "camera_height":
        st = 4
        z = rel[::st, ::st]
        vs, us = np.mgrid[0 : prior.height : st, 0 : prior.width : st] + 0.5
        ok = z > 0
        pts = np.stack([(us[ok] - prior.cx) * z[ok] / prior.fx, (vs[ok] - prior.cy) * z[ok] / prior.fy, z[ok]], 1)
        if len(pts) < 50:
            raise DropUnit("depth_scale_unrecoverable", "too few valid pixels for a floor plane")
        up = CameraPrior(prior.width, prior.height, prior.fx, prior.fy, prior.cx, prior.cy, pitch=pitch).up_cam()
        thresh = 0.01 * float(np.median(pts[:, 2]))
        pl = ransac_plane(pts, rng, thresh, up, np.deg2rad(30.0))
        if pl is None or len(pl.inliers) < 0.05 * len(pts) or pl.d <= 0:
            raise DropUnit("depth_scale_unrecoverable", "no floor plane found for camera-height scale recovery")
        s = camera_height / pl.d  # n.p + d = 0 with n up: the camera (origin) lies d above the plane
        return (rel * s).astype(np.float32), "scale:camera_height", {"scale": s, "floor_inliers": int(len(pl.inliers))}
    raise ValueError(f"unknown scale recovery method {method!r} (known: {', '.join(METHODS)})")
