"""Answer points that lie on the object's box surface (scan sources whose masks come from boxes alone).

A box-only mask is every pixel whose depth point lies inside the box, so whatever unannotated thing sits
inside the box (a TV in a TV unit's niche, an office chair under a desk) is part of the mask, and the mask's
interior pole can land on it. Box-shaped furniture shows its own faces where the camera ray enters its box;
a point whose depth lies far behind that entry (more than `max_point_recess`, 0.30 m) is in an opening of
the box: on what stands in it as likely as on the object. Its answer point is withheld (counted as
`answer_point_recessed`); verify recomputes the recess at the answer pixel by its own code (qa/verify_recess.py).

Measured on the shared frames (ScanNet scene0000_00 00000/00011/00102, SUN RGB-D 000001/2): the cabinet of
00102 (a 1.5 m box round a TV unit) has its pole 0.70 m behind its entry face, on the shelf above the TV;
every other pole lies 0.22 m or less behind it except SUN 000001's bed (2.16 m: the headboard at the back
of a bed box whose foot end is hidden), withheld too. Choosing the point among the pixels at the entry face
instead was tried and rejected: the desk box of 00011 holds the office chair's backrest at its front face.
"""

from __future__ import annotations

import numpy as np

from refspatial_gen.core.camera import Camera
from refspatial_gen.core.geometry import Box3D
from refspatial_gen.core.mask import answer_pixel
from refspatial_gen.core.model import ObjectInstance
from refspatial_gen.sources.scan.visibility import pixel_rays

WITHHELD = "withheld_recessed"
REASON = "answer_point_recessed"


def entry_depth(cam: Camera, box: Box3D, x: int, y: int) -> float:
    """Camera depth (z) where pixel (x, y)'s ray enters the box (0 when the camera is inside), inf on a miss."""
    ray = pixel_rays(cam, x, y, x + 1, y + 1)[0, 0]
    R, o = cam.world_from_cam[:3, :3], cam.world_from_cam[:3, 3]
    dl = (R @ ray) @ box.rotation
    ol = (o - box.center) @ box.rotation
    half = box.size / 2.0
    with np.errstate(divide="ignore", invalid="ignore"):
        t1, t2 = (-half - ol) / dl, (half - ol) / dl
    t_in = float(np.nanmax(np.minimum(t1, t2)))
    t_out = float(np.nanmin(np.maximum(t1, t2)))
    return max(t_in, 0.0) if t_in <= t_out and t_out > 1e-6 else float("inf")


def recess(cam: Camera, depth: np.ndarray, box: Box3D, mask: np.ndarray, x: int, y: int) -> float | None:
    """Metres the object's depth at pixel (x, y) (median of its mask's known depth in a 5x5 window) lies
    behind where the ray enters the box; None without known depth there."""
    y0, x0 = max(0, y - 2), max(0, x - 2)
    win, m = depth[y0 : y + 3, x0 : x + 3], mask[y0 : y + 3, x0 : x + 3]
    d = win[m & (win > 0)]
    t = entry_depth(cam, box, x, y)
    if len(d) == 0 or not np.isfinite(t):
        return None
    return float(np.median(d)) - t


def box_only(o: ObjectInstance) -> bool:
    """A named scan object whose mask comes from its box alone (no per-point instance label trimmed it)."""
    p = o.provenance or {}
    return p.get("source") == "scan" and "instance" not in p and not p.get("distractor_only") and o.mask is not None


def withhold_recessed(objects: list[ObjectInstance], cam: Camera, depth: np.ndarray, max_recess: float) -> int:
    """Mark box-only objects whose answer pixel (core.mask.answer_pixel, as graph/scene.py picks it) lies
    more than `max_recess` metres behind the box's entry face; graph/scene.py then gives them no answer
    point. Returns how many were marked."""
    n = 0
    for o in objects:
        if not box_only(o):
            continue
        m = o.mask.decode()
        px = answer_pixel(m)
        r = None if px is None else recess(cam, depth, o.box, m, int(px[0]), int(px[1]))
        if r is not None:
            o.provenance["point_recess_m"] = round(r, 3)
        if r is not None and r > max_recess:
            o.provenance["answer_point"] = WITHHELD
            n += 1
    return n
