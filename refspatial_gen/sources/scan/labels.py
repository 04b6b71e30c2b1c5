"""Per-point instance labels of a scan, and which annotated box each instance is.

Box-annotated scans say where an object is, not which of the points in its box are the object: the
office chair pushed under a desk lies inside the desk's box. ScanNet ships per-point instances (what its
boxes were computed from): `<scene>_vh_clean_2.0.010000.segs.json` (a segment id per mesh vertex) and
`<scene>.aggregation.json` (segment groups = instances, `objectId` + `label`). Other exports put an
instance id on each PLY vertex. When labels exist, a pixel belongs to a box only when the point it shows
(the same z-buffer as the splatted depth) is that box's instance (frames.py).

Files are found next to `scene.json` (or named there: `segs_file`, `aggregation_file`); they must label
exactly the points of the scene's point file (the mesh vertices), else they are ignored with a note.
An instance is a box's when the box's object JSON names it (`instance_id`, or `object_id` = ScanNet's
objectId) or, failing that, when most of the instance's points lie in that box and it is the instance
with the most points there.
"""

from __future__ import annotations

import json
from pathlib import Path
from typing import Any

import numpy as np

VERTEX_PROPERTIES = ("instance", "instance_id", "objectId", "object_id")


def _first(root: Path, names: list[str | None], patterns: tuple[str, ...]) -> Path | None:
    for n in names:
        if n and (root / n).is_file():
            return root / n
    for pat in patterns:
        hits = sorted(root.glob(pat))
        if hits:
            return hits[0]
    return None


STRUCTURAL = ("wall", "floor", "ceiling")


def scannet_labels(
    root: Path, meta: dict[str, Any], n_points: int, structural: set[int] | None = None
) -> tuple[np.ndarray | None, str]:
    """Per-point instance ids (0 = none) from ScanNet's segs + aggregation files, and a note. The ids of
    wall/floor/ceiling instances are added to `structural` when given."""
    segs = _first(root, [meta.get("segs_file")], ("*.segs.json",))
    agg = _first(root, [meta.get("aggregation_file")], ("*.aggregation.json",))
    if segs is None or agg is None:
        return None, "no segs/aggregation files"
    try:
        seg_idx = np.asarray(json.loads(segs.read_text(encoding="utf-8"))["segIndices"], np.int64)
        groups = json.loads(agg.read_text(encoding="utf-8"))["segGroups"]
    except (OSError, ValueError, KeyError, TypeError) as e:
        return None, f"unreadable labels: {e}"
    if len(seg_idx) != n_points:
        return None, f"{segs.name} labels {len(seg_idx)} vertices, the point file has {n_points}"
    seg_to_inst: dict[int, int] = {}
    for g in sorted(groups, key=lambda g: int(g.get("objectId", g.get("id", 0)))):
        oid = int(g.get("objectId", g.get("id", 0))) + 1
        if structural is not None and str(g.get("label", "")).lower() in STRUCTURAL:
            structural.add(oid)
        for s in g.get("segments", []):
            seg_to_inst.setdefault(int(s), oid)
    keys = np.array(sorted(seg_to_inst), np.int64)
    vals = np.array([seg_to_inst[k] for k in keys], np.int64)
    out = np.zeros(n_points, np.int64)
    if len(keys):
        pos = np.clip(np.searchsorted(keys, seg_idx), 0, len(keys) - 1)
        hit = keys[pos] == seg_idx
        out[hit] = vals[pos[hit]]
    return out, f"{segs.name} + {agg.name}"


def ply_vertex_labels(path: Path, n_points: int) -> tuple[np.ndarray | None, str]:
    """Per-point instance ids from a vertex property of the PLY (instance, instance_id, objectId...)."""
    import trimesh

    try:
        raw = trimesh.load(str(path), process=False).metadata.get("_ply_raw", {})
        data = raw["vertex"]["data"]
    except (OSError, ValueError, KeyError, TypeError, AttributeError):
        return None, "no vertex properties"
    for name in VERTEX_PROPERTIES:
        if name in (data.dtype.names or ()):
            lab = np.asarray(data[name], np.int64)
            if len(lab) == n_points:
                return lab, f"{path.name}: vertex property {name!r}"
    return None, "no instance vertex property"


def box_instances(
    boxes: list,
    points: np.ndarray,
    labels: np.ndarray,
    explicit: dict[int, int],
    min_share: float = 0.5,
    pad: float = 0.02,
) -> dict[int, int]:
    """Box id -> instance id: the object JSON's own id when given, else the instance with the most points
    in the box, provided most (`min_share`) of that instance lies in it (a wall crossing the box is not it)."""
    out: dict[int, int] = {}
    sizes = np.bincount(labels[labels > 0]) if (labels > 0).any() else np.zeros(1)
    for b in boxes:
        if b.id in explicit:
            out[b.id] = explicit[b.id]
            continue
        inside = labels[b.box.contains(points, pad)]
        inside = inside[inside > 0]
        if not inside.size:
            continue
        counts = np.bincount(inside, minlength=len(sizes))
        k = int(np.argmax(counts))
        if counts[k] >= min_share * sizes[k]:
            out[b.id] = k
    return out
