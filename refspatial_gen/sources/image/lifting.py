"""Every usable annotation of a photo lifted to a 3D box (lift.py does one object) and, for box annotations
with measured depth, a visible mask cut by depth (boxseg.py) and amodal completion (amodal.py)."""

from __future__ import annotations

from dataclasses import replace
from typing import Any

import numpy as np

from refspatial_gen.core.camera import Camera
from refspatial_gen.core.geometry import Box3D
from refspatial_gen.sources.image import filters as F


def lift_candidates(
    live: list[F.Candidate],
    depth: np.ndarray,
    cam: Camera,
    support_z: list[float],
    walls: list[tuple[np.ndarray, float]],
    cfg: dict[str, Any],
    est_name: str,
) -> None:
    """Give each live candidate its box (or drop it with a reason), smallest annotations first, in place."""
    from refspatial_gen.sources.image.lift import LiftParams

    H, W = depth.shape
    params = LiftParams(
        max_points=cfg["max_points_per_object"],
        min_points=cfg["min_points"],
        min_valid_fraction=cfg["min_valid_depth_fraction"],
        complete_depth=cfg["complete_depth"],
        snap_distance=0.25 if cfg["snap_to_support"] else 0.0,
    )
    claimed = np.zeros((H, W), bool)  # box annotations: pixels already taken by a smaller box's object
    layered = _box_masks(live, depth, cam, support_z, walls, params) if est_name != "geometric" else {}
    pending: list[F.Candidate] = []  # box annotations lifted, awaiting amodal completion
    for c in sorted(live, key=lambda c: (c.segmentation, int(c.mask.sum()), c.ann_id)):
        if c.reason is not None:
            continue
        _lift_one(c, layered.get(id(c)), claimed, pending, depth, cam, support_z, walls, params, cfg, est_name)
    _complete_box_annotations([c for c in pending if c.reason is None], depth, cam, support_z, params)


def _lift_one(
    c: F.Candidate,
    bm: np.ndarray | None,
    claimed: np.ndarray,
    pending: list[F.Candidate],
    depth: np.ndarray,
    cam: Camera,
    support_z: list[float],
    walls: list[tuple[np.ndarray, float]],
    params: Any,
    cfg: dict[str, Any],
    est_name: str,
) -> None:
    """One candidate: its pixels with depth lifted to a box; a box annotation's mask refined by depth
    (its pixels added to `claimed`); box-layered ones fitted to their 2D box and queued in `pending`."""
    from refspatial_gen.sources.image.amodal import fit_to_box2d
    from refspatial_gen.sources.image.lift import lift_object

    H, W = depth.shape
    if bm is not None:
        ys, xs = np.nonzero(bm & ~claimed)
    else:
        ys, xs = np.nonzero(c.mask & ~claimed) if not c.segmentation else np.nonzero(c.mask)
    zz = depth[ys, xs]
    ok = zz > 0
    if ok.sum() < params.min_points or ok.mean() < params.min_valid_fraction:
        F.drop(c, "low_valid_depth")
        return
    ys, xs, zz = ys[ok], xs[ok], zz[ok]
    weights = None
    if not c.segmentation and bm is None:  # box annotation: the object fills the box centre, clutter its rim
        x0, y0, x1, y1 = c.bbox2d
        cx_, cy_, hw, hh = (x0 + x1) / 2, (y0 + y1) / 2, (x1 - x0) / 4, (y1 - y0) / 4
        weights = np.where((np.abs(xs - cx_) <= hw) & (np.abs(ys - cy_) <= hh), 1.0, 0.2)
    if bm is not None:
        out = lift_object(xs, ys, zz, cam, replace(params, complete_depth=False), support_z, walls, preselected=True)
    else:
        out = lift_object(xs, ys, zz, cam, params, support_z, walls, weights)
    if isinstance(out, str):
        F.drop(c, out)
        return
    if bm is not None:  # box annotation: fit to its 2D box now, support and depth completion below
        out.box, n_fit = fit_to_box2d(out.box, c.bbox2d, cam)
        out.notes.update(n_fit)
        pending.append(c)
    if str(c.provenance.get("contact", "")).startswith("behind:") and out.box.bottom_z > 0:
        # its foot is hidden behind the occluder: it stands on the ground (amodal completion)
        out.box = _with_bottom(out.box, 0.0)
        out.notes["occluded_completed"] = True
    c.box = out.box
    c.provenance.update({k: v for k, v in out.notes.items()})
    c.provenance["points"] = out.points_used
    if not c.segmentation and est_name != "geometric":
        # a box annotation: the visible mask is the box pixels whose 3D point lies on the object
        allw = cam.cam_to_world(cam.backproject(xs + 0.5, ys + 0.5, zz))
        vis = out.keep_pixels & out.visible_box.contains(allw, pad=0.03)
        m = np.zeros((H, W), bool)
        m[ys[vis], xs[vis]] = True
        if m.sum() < cfg["min_mask_area"]:  # too few box pixels have depth on the object
            F.drop(c, "too_small")
            return
        c.mask = m
        claimed |= m
        c.provenance["mask"] = "box_refined_by_depth"
    else:
        c.provenance["mask"] = "segmentation" if c.segmentation else "box"


def _with_bottom(box: Box3D, bottom: float) -> Box3D:
    c, s = box.center.copy(), box.size.copy()
    top = box.top_z
    c[2], s[2] = (top + bottom) / 2, top - bottom
    return Box3D(c, s, box.rotation)


def _box_masks(
    live: list[F.Candidate],
    depth: np.ndarray,
    cam: Camera,
    support_z: list[float],
    walls: list[tuple[np.ndarray, float]],
    params,
) -> dict[int, np.ndarray]:
    """Box annotations: visible masks by depth layering of the overlapping boxes (boxseg.py), by id(c)."""
    from refspatial_gen.sources.image.boxseg import assign_boxes

    boxes = [c for c in live if c.reason is None and not c.segmentation]
    if not boxes:
        return {}
    H, W = depth.shape
    vs, us = np.mgrid[0:H, 0:W]
    ok = depth > 0
    world = np.zeros((H, W, 3))
    world[ok] = cam.cam_to_world(cam.backproject(us[ok] + 0.5, vs[ok] + 0.5, depth[ok]))
    bm = assign_boxes(depth, world, [c.bbox2d for c in boxes], support_z, walls, band=params.plane_band, cam=cam)
    for c, note in zip(boxes, bm.notes):
        c.provenance["box_layering"] = note
    return {id(c): m for c, m in zip(boxes, bm.masks)}


def _complete_box_annotations(
    cands: list[F.Candidate], depth: np.ndarray, cam: Camera, support_z: list[float], params
) -> None:
    """Amodal completion of lifted box annotations (amodal.py): down to what they stand on (a support
    plane or another object's top) when the added part would be hidden, then along the view direction."""
    from refspatial_gen.sources.image.amodal import complete_to_support, supports_below
    from refspatial_gen.sources.image.lift import complete_along_view

    def deep(b):
        return complete_along_view(b, cam.position[:2])[0] if params.complete_depth else b

    boxes = {id(c): c.box for c in cands}  # after fitting to the 2D box, before any completion
    footprints = {k: deep(b) for k, b in boxes.items()}
    for c in cands:
        others = [(boxes[id(o)], footprints[id(o)]) for o in cands if o is not c]
        sup = supports_below(boxes[id(c)], footprints[id(c)], support_z, others, params.plane_band)
        box, notes = complete_to_support(boxes[id(c)], depth, cam, sup, params.plane_band)
        if params.complete_depth:
            box, grow = complete_along_view(box, cam.position[:2])
            if grow > 0:
                notes["depth_completed"] = round(grow, 4)
        c.box = box
        c.provenance.update(notes)
