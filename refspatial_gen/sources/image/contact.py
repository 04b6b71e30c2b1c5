"""Which objects of a geometric-depth photo have no trusted 3D position (recorded per object as
provenance["position_unseen"]; qa/faint_photo.py withholds position and size claims on them, verify re-checks).

Geometric depth places an object where the bottom edge of its mask meets the ground (depth/geometric.py).
That is a guess when the edge is not the object's foot:
  cut_by_border       the mask reaches an image border (graph/visibility.partly_seen): a piece of the object
  foot_at_border      its lowest row lies within `foot_border_margin` x the height of the bottom edge: the
                      foot is at or below the edge (a half-framed elephant, COCO 384553)
  occluded_in_front   it stands behind an object that hides its foot
  off_ground_category  a category whose bottom edge is not a floor contact (truth/contact.py: a sink,
                      a held umbrella or handbag) placed on the ground
"""

from __future__ import annotations

from typing import Any

from refspatial_gen.truth.contact import OFF_GROUND


def position_unseen(obj: Any, height: int, foot_border_margin: float) -> str | None:
    """Why `obj`'s lifted position is not trusted, or None."""
    from refspatial_gen.graph.visibility import partly_seen

    why = partly_seen(obj)
    if why is not None:
        return str(why)
    prov = obj.provenance or {}
    if obj.mask is not None and obj.mask.area:
        rows = obj.mask.decode().any(axis=1).nonzero()[0]
        if len(rows) and rows[-1] >= height * (1.0 - foot_border_margin) - 1:
            return "foot_at_border"
    if prov.get("contact_truncated"):
        return "foot_at_border"
    if obj.category in OFF_GROUND and prov.get("contact") == "ground":
        return "off_ground_category"
    return None


def mark_unseen(objects: list[Any], height: int, foot_border_margin: float) -> dict[str, int]:
    """Record provenance["position_unseen"] on every object without a trusted position; counts by reason."""
    counts: dict[str, int] = {}
    for o in objects:
        why = position_unseen(o, height, foot_border_margin)
        if why is not None:
            o.provenance["position_unseen"] = why
            key = f"position_unseen_{why}"
            counts[key] = counts.get(key, 0) + 1
    return dict(sorted(counts.items()))
