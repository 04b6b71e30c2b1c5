"""Lifting accuracy on SUN RGB-D frames treated as plain photos (provided depth + 2D boxes only).

The lifted boxes are compared with SUN RGB-D's ground-truth 3D boxes, which the image source never
reads: centre error (camera frame, metres) and agreement of pairwise relations. Relations are judged
in each side's own frame (lifted: our estimated gravity; ground truth: SUN's Rtilt) with the room-scale
margins of graph/constants.py, and counted only on pairs where both sides are decided.
"""

from __future__ import annotations

import json
from pathlib import Path
from typing import Any

import numpy as np

from refspatial_gen.core.geometry import Box3D, rot_z

F_SUN = np.array([[1.0, 0, 0], [0, 0, -1.0], [0, 1.0, 0]])  # SUN upright (x right, y fwd, z up) -> OpenCV
LATERAL, DEPTH, VERTICAL, SIZE_ABS, SIZE_REL, VOL_REL = 0.10, 0.10, 0.10, 0.05, 0.10, 0.20
RELATIONS = ("left", "front", "above", "bigger", "taller", "wider")

EVAL_CONFIG = {
    "format": "sunrgbd",
    "depth": {"estimator": "provided"},
    "intrinsics": "provided",
    "complete_categories": False,
    "min_objects": 1,
    "min_instance_spread": 0.0,
}


def gt_boxes(sample_dir: Path) -> tuple[list[Box3D], np.ndarray]:
    """SUN ground-truth boxes in SUN's upright frame, and cam_from_world (3x3) = F @ Rtilt.T."""
    a = json.loads((sample_dir / "annotation.json").read_text(encoding="utf-8"))
    boxes = [Box3D(np.array(o["center"]), np.array(o["size"]), rot_z(float(o["yaw"]))) for o in a["objects"]]
    return boxes, F_SUN @ np.asarray(a["Rtilt"], float).T


def _sign(v: float, margin: float) -> int:
    return 0 if abs(v) <= margin else (1 if v > 0 else -1)


def _size_cmp(a: float, b: float, abs_m: float, rel: float) -> int:
    return _sign(a - b, max(abs_m, rel * max(a, b)))


def pair_relations(A: Box3D, B: Box3D, R_cw: np.ndarray, t_cw: np.ndarray) -> dict[str, int]:
    """+1 (holds for A vs B), -1 (mirror holds), 0 (undecided), judged with world z up and camera R_cw, t_cw."""
    ca, cb = R_cw @ A.center + t_cw, R_cw @ B.center + t_cw
    na = float((A.corners() @ R_cw.T + t_cw)[:, 2].min())
    nb = float((B.corners() @ R_cw.T + t_cw)[:, 2].min())
    front = _sign(nb - na, DEPTH)
    if front != 0 and np.sign(cb[2] - ca[2]) != front:
        front = 0
    wa, wb = float(max(A.size[0], A.size[1])), float(max(B.size[0], B.size[1]))
    return {
        "left": _sign(cb[0] - ca[0], LATERAL),
        "front": front,
        "above": _sign(A.center[2] - B.center[2], VERTICAL),
        "bigger": _sign(A.volume - B.volume, VOL_REL * max(A.volume, B.volume)),
        "taller": _size_cmp(A.height, B.height, SIZE_ABS, SIZE_REL),
        "wider": _size_cmp(wa, wb, SIZE_ABS, SIZE_REL),
    }


def compare_sunrgbd(root: str | Path, config: dict[str, Any] | None = None, seed: int = 0) -> dict[str, Any]:
    """Lift every SUN RGB-D sample under `root` and compare with its ground truth."""
    from refspatial_gen.sources.image.annotations import load_collection
    from refspatial_gen.sources.image.source import build_frame

    cfg = dict(EVAL_CONFIG, **(config or {}))
    coll = load_collection(root, "sunrgbd")
    errors, per_object, frames = [], [], {}
    agree = {r: [0, 0] for r in RELATIONS}
    gravity_err = []
    per_frame: dict[str, dict[str, Any]] = {}
    for iid in coll.ids():
        frame = build_frame(coll, coll.images[iid], np.random.default_rng(seed), cfg)
        frames[iid] = frame
        gts, R_gt = gt_boxes(Path(root) / iid)
        cam = frame.camera
        T = cam.cam_from_world
        up_gt = R_gt @ np.array([0.0, 0.0, 1.0])
        gravity_err.append(float(np.degrees(np.arccos(np.clip(up_gt @ (T[:3, :3] @ [0.0, 0.0, 1.0]), -1, 1)))))
        objs = frame.objects
        mine = [0, 0]
        for o in objs:
            g = gts[int(o.provenance["annotation_id"])]
            c_lift = cam.world_to_cam(o.box.center)[0]
            c_gt = R_gt @ g.center
            e = float(np.linalg.norm(c_lift - c_gt))
            errors.append(e)
            per_object.append(
                {
                    "image": iid,
                    "category": o.category,
                    "error_cm": round(100 * e, 1),
                    "lifted_size": [round(float(s), 2) for s in o.box.size],
                    "gt_size": [round(float(s), 2) for s in g.size],
                }
            )
        for i in range(len(objs)):
            for j in range(i + 1, len(objs)):
                A, B = objs[i], objs[j]
                la = pair_relations(A.box, B.box, T[:3, :3], T[:3, 3])
                ga = pair_relations(
                    gts[int(A.provenance["annotation_id"])], gts[int(B.provenance["annotation_id"])], R_gt, np.zeros(3)
                )
                for r in RELATIONS:
                    if la[r] != 0 and ga[r] != 0:
                        agree[r][1] += 1
                        agree[r][0] += int(la[r] == ga[r])
                        mine[1] += 1
                        mine[0] += int(la[r] == ga[r])
        per_frame[iid] = {
            "objects": len(objs),
            "annotated": len(gts),
            "relation_pairs": mine[1],
            "relation_agreement": round(mine[0] / mine[1], 4) if mine[1] else None,
            "gravity_error_deg": round(gravity_err[-1], 2),
        }
    total = sum(v[1] for v in agree.values())
    ok = sum(v[0] for v in agree.values())
    return {
        "objects": len(errors),
        "median_centre_error_cm": round(100 * float(np.median(errors)), 1) if errors else None,
        "mean_centre_error_cm": round(100 * float(np.mean(errors)), 1) if errors else None,
        "relation_pairs": total,
        "relation_agreement": round(ok / total, 4) if total else None,
        "by_relation": {r: {"agree": a, "decided_both": n} for r, (a, n) in agree.items()},
        "gravity_error_deg": [round(g, 2) for g in gravity_err],
        "per_object": per_object,
        "frames": frames,
        "per_frame": per_frame,
    }
