"""Box-less RGB-D scans: objects from detection + masks on key frames, lifted with the measured depth and
fused across frames (fusion.py), handed to the scan source as if a box file had listed them.

The trajectory reader calls `fused_boxes` when a sequence has no box file and its config has a
`perception:` section. The key frames are the source's own (every `keyframe_stride`-th view of the
sequence), at most `fusion.max_frames` of them, evenly spaced; frames are detected in fixed blocks of
`batch_size` (the same batches whichever worker asks). A posed sequence is fused as a whole; a frame without
a pose (identity) is its own scene. Fusion works in the reader's levelled world (z up when the floor was
found) and the boxes are returned in the trajectory's own world frame, where box files live, so the
reader levels them with everything else. The result is computed once per worker and sequence.
"""

from __future__ import annotations

import json
from functools import lru_cache
from pathlib import Path
from typing import Any

import numpy as np

from refspatial_gen.core.errors import DropUnit
from refspatial_gen.core.geometry import Box3D
from refspatial_gen.perception import fusion
from refspatial_gen.perception.cache import array_hash
from refspatial_gen.perception.captions import attributes_from_views
from refspatial_gen.perception.pipeline import Item, get_perceiver


def key_views(all_views: list[str], seq: str, stride: int, max_frames: int) -> list[str]:
    """The sequence's key frames: every `stride`-th view, then at most `max_frames`, evenly spaced."""
    from refspatial_gen.sources.scan.source import thin

    views = thin([v for v in all_views if v.startswith(f"{seq}/")], stride)
    if len(views) > max_frames:
        pick = np.linspace(0, len(views) - 1, max_frames).round().astype(int)
        views = [views[i] for i in sorted(set(pick.tolist()))]
    return views


def fused_boxes(
    reader_cls: type, root: Path, seq: str, view_id: str, posed: bool, config: dict[str, Any]
) -> tuple[list, dict[str, Any]]:
    """ScanBoxes (trajectory world frame) of the objects perception finds in the view's sequence, and a
    record for the view's meta (models, key frames, what fusion dropped)."""
    base = {k: v for k, v in config.items() if k != "perception"}
    group = None if posed else view_id
    boxes, note = _fused(
        reader_cls,
        str(Path(root).resolve()),
        seq,
        group,
        json.dumps(base, sort_keys=True, default=str),
        json.dumps(config["perception"], sort_keys=True),
    )
    return list(boxes), {"perception": json.loads(note)}


@lru_cache(maxsize=8)
def _fused(
    reader_cls: type, root: str, seq: str, single: str | None, base_json: str, section_json: str
) -> tuple[tuple, str]:
    from refspatial_gen.sources.scan.view import ScanBox

    reader = reader_cls()
    base = json.loads(base_json)
    P = get_perceiver(json.loads(section_json))
    fz = P.cfg["fusion"]
    vids = (
        [single]
        if single
        else key_views(reader.views(Path(root), base), seq, int(base.get("keyframe_stride") or 1), fz["max_frames"])
    )
    views = []
    for vid in vids:
        try:
            views.append(reader.read(Path(root), vid, base))
        except DropUnit:
            continue  # that frame's own unit reports why
    if not views:
        return (), json.dumps({"key_frames": 0, "objects": 0})
    items = [Item(v.view_id, array_hash(v.rgb), v.rgb) for v in views]
    results = []
    for s in range(0, len(items), P.rt.batch_size):
        results += P.run(items[s : s + P.rt.batch_size], filters=False, depth=False)
    obs = []
    for f, (v, r) in enumerate(zip(views, results)):
        if isinstance(r, DropUnit) or v.depth is None:
            continue
        for k, d in enumerate(r.detections):
            m = r.masks[k] if r.masks is not None else _box_mask(d.box, v.depth.shape)
            codes, pts = fusion.lift(m, v.depth, v.camera, fz["voxel"])
            if len(codes):
                obs.append(fusion.Observation(f, d.label, d.score, codes, m, d.box, pts))
    known = bool(views[0].camera.gravity_known)
    objs, drops = fusion.finish(
        fusion.associate(obs, fz["voxel"], fz["match_overlap"]), fz["voxel"], fz["min_views"], fz["min_points"], known
    )
    T = np.array(views[0].meta.get("world_leveling") or np.eye(4), float)
    Ti = np.linalg.inv(T)
    out = []
    for k, (obj, box) in enumerate(objs):
        raw = Box3D(Ti[:3, :3] @ box.center + Ti[:3, 3], box.size, Ti[:3, :3] @ box.rotation)
        rgbs = [views[o.frame].rgb for o in obj.observations]
        attrs = attributes_from_views(rgbs, [o.mask for o in obj.observations]) if P.cfg["captions"]["colour"] else {}
        prov = {
            "annotation": "perception",
            "perception": {
                "views": sorted({views[f].view_id for f in obj.frames}),
                "detections": len(obj.observations),
                "score": round(float(max(obj.scores)), 4),
                "voxels": len(obj.voxels),
            },
        }
        out.append(ScanBox(k + 1, obj.label, raw, None, None, None, attrs, prov))
    note = {
        "models": P.model_meta(),
        "key_frames": [v.view_id for v in views],
        "detections": len(obs),
        "objects": len(out),
        "fusion_drops": drops,
        "frames_without_detections": sum(isinstance(r, DropUnit) for r in results),
    }
    return tuple(out), json.dumps(note, sort_keys=True)


def _box_mask(box, shape) -> np.ndarray:
    from refspatial_gen.sources.image.rle import box_mask

    return box_mask(box, shape[0], shape[1])
