"""Truth floors of the scene graph: which objects a person can see well enough to be asked about, and
which objects (and frames) can back a metric or size claim.

Why: `verify` proves answers agree with the stored scene; it cannot tell that a referent is a 20-pixel
sliver nobody would notice, or that a photo's person was lifted 3.7 m tall. An object below the
visibility floor keeps its place in the scene (it still counts when "the leftmost cup" or "how many" is
decided: qa/faint.py) but gets no phrase and no answer point, so it is never named, marked, offered as an
option or pointed at. An object whose size its category cannot vouch for (truth/sizes.py), or any object
of a frame whose metric scale is unverified, or on a photo an object cut by the image border or hidden
in part by an object in front, gets `metric: False`: no distance, size or height value and no size
comparison is asked about it.

Recipe (`graph: truth:`, every key optional; docs/quality.md has the measurements behind the defaults):
  min_visible_px        visible mask pixels an object needs (default 150)
  min_visible_fraction  visible / unoccluded projected pixels, where the source knows it (default 0.25)
  min_in_view_fraction  share of the object's 3D box inside the camera's view (default 0.5)
  size_tolerance        widen every category size range by this fraction (default 0.0)
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

import numpy as np

from refspatial_gen.core.errors import RecipeError
from refspatial_gen.schema import Field, check_section

DEFAULTS = {"min_visible_px": 150, "min_visible_fraction": 0.25, "min_in_view_fraction": 0.5, "size_tolerance": 0.0}
TRUTH_FIELDS: dict[str, Field] = {
    "min_visible_px": Field(
        int,
        default=DEFAULTS["min_visible_px"],
        min=0,
        max=1_000_000,
        doc="visible mask pixels every referent, option and mark needs",
    ),
    "min_visible_fraction": Field(
        float,
        default=DEFAULTS["min_visible_fraction"],
        min=0.0,
        max=1.0,
        doc="visible / unoccluded projected pixels (where the source measures it)",
    ),
    "min_in_view_fraction": Field(
        float,
        default=DEFAULTS["min_in_view_fraction"],
        min=0.0,
        max=1.0,
        doc="share of the object's 3D box inside the camera's view (image border cut)",
    ),
    "size_tolerance": Field(
        float,
        default=DEFAULTS["size_tolerance"],
        min=0.0,
        max=10.0,
        doc="widen every category size range by this fraction before a metric question",
    ),
}
# reasons (graph.meta["truth"] keys, node attribute "below_floor")
FEW_PIXELS, LOW_FRACTION, OUT_OF_VIEW = "below_floor_pixels", "below_floor_fraction", "below_floor_border"
SCALE_UNVERIFIED = "metric_scale_unverified"
CUT_BY_BORDER = "cut_by_border"  # photos: the mask reaches the image border, the object goes on outside
OCCLUDED = "occluded_in_front"  # photos: another object in front hides part of it (its foot)
BORDER_PX = 3  # mask pixels in the outer BORDER_PX rows/columns (within 2 px of the edge) touch the border
GRID = 12  # points per box axis for the in-view share (share error <= 1/24 for a border cut)


@dataclass(frozen=True)
class Floor:
    min_visible_px: int = DEFAULTS["min_visible_px"]  # type: ignore[assignment]
    min_visible_fraction: float = DEFAULTS["min_visible_fraction"]
    min_in_view_fraction: float = DEFAULTS["min_in_view_fraction"]
    size_tolerance: float = DEFAULTS["size_tolerance"]

    def to_json(self) -> dict[str, float]:
        return {
            "min_in_view_fraction": round(float(self.min_in_view_fraction), 6),
            "min_visible_fraction": round(float(self.min_visible_fraction), 6),
            "min_visible_px": int(self.min_visible_px),
            "size_tolerance": round(float(self.size_tolerance), 6),
        }


def floor_of(config: dict[str, Any] | None) -> Floor:
    """The floor from a graph config's `truth` mapping (already checked by `check_truth_section`)."""
    raw = dict((config or {}).get("truth") or {})
    unknown = set(raw) - set(TRUTH_FIELDS)
    if unknown:
        raise ValueError(f"unknown graph.truth key(s) {sorted(unknown)}; known: {sorted(TRUTH_FIELDS)}")
    vals = {k: (raw[k] if raw.get(k) is not None else f.default) for k, f in TRUTH_FIELDS.items()}
    return Floor(
        int(vals["min_visible_px"]),
        float(vals["min_visible_fraction"]),
        float(vals["min_in_view_fraction"]),
        float(vals["size_tolerance"]),
    )


def check_truth_section(graph: Any, file: str, lines: dict[tuple[Any, ...], int], errors: list[RecipeError]) -> None:
    """Recipe check of `graph: truth:` (file:line errors before any work)."""
    if isinstance(graph, dict) and graph.get("truth") is not None:
        check_section(graph["truth"], TRUTH_FIELDS, file, lines, ("graph", "truth"), errors)


def in_view_fractions(camera: Any, boxes: list[Any]) -> np.ndarray:
    """Per box: share of a GRID^3 lattice inside it that projects inside the image in front of the camera, i.e.
    how much of the object the image border (or the camera's back) leaves in view. One vectorised pass."""
    if not boxes:
        return np.zeros(0)
    t = (np.arange(GRID) + 0.5) / GRID - 0.5
    unit = np.stack(np.meshgrid(t, t, t, indexing="ij"), -1).reshape(-1, 3)  # (G, 3)
    sizes = np.array([b.size for b in boxes], float)  # (n, 3)
    rots = np.array([b.rotation for b in boxes], float)  # (n, 3, 3)
    centres = np.array([b.center for b in boxes], float)
    pts = centres[:, None, :] + np.einsum("ngk,njk->ngj", unit[None] * sizes[:, None, :], rots)
    cam = camera.world_to_cam(pts.reshape(-1, 3))
    z = cam[:, 2]
    ok = z > 1e-3
    zs = np.where(ok, z, 1.0)
    u = camera.fx * cam[:, 0] / zs + camera.cx
    v = camera.fy * cam[:, 1] / zs + camera.cy
    inside = ok & (u >= 0) & (u < camera.width) & (v >= 0) & (v < camera.height)
    return np.asarray(inside.reshape(len(boxes), -1).mean(axis=1), float)


def floor_reasons(geom: Any, floor: Floor) -> list[str | None]:
    """Per object position: why it is below the visibility floor, or None."""
    out: list[str | None] = []
    for i, o in enumerate(geom.frame.objects):
        if int(geom.mask_area[i]) < floor.min_visible_px:
            out.append(FEW_PIXELS)
        elif float(o.visible_fraction) < floor.min_visible_fraction:
            out.append(LOW_FRACTION)
        elif geom.in_view[i] < floor.min_in_view_fraction:
            out.append(OUT_OF_VIEW)
        else:
            out.append(None)
    return out


def partly_seen(obj: Any) -> str | None:
    """Why a photo's object is only partly seen, or None: its mask touches the image border (within
    BORDER_PX) or the depth estimator found it standing behind another object that hides its foot. Its
    lifted box is then a piece of the object (a bench cut by the frame judged smaller than an oven, an
    elephant half under water 1.11 m tall: audit, issue 15), so no size or metric claim rests on it."""
    if obj.mask is not None and obj.mask.area:
        m = obj.mask.decode()
        b = BORDER_PX
        if m[:b].any() or m[-b:].any() or m[:, :b].any() or m[:, -b:].any():
            return CUT_BY_BORDER
    prov = obj.provenance or {}
    if prov.get("behind") or str(prov.get("contact", "")).startswith("behind:"):
        return OCCLUDED
    return None


def metric_reasons(geom: Any, floor: Floor) -> list[str | None]:
    """Per object position: why no metric or size question may be asked about it, or None.

    The size checked is the gravity-aligned box: (larger, smaller horizontal extent, height). The largest
    extent is only checked from above (a cut or hidden object's box is a lower bound on the real one)."""
    from refspatial_gen.truth.sizes import check_size

    scale = geom.frame.meta.get("metric_scale")
    if isinstance(scale, dict) and scale.get("reliable") is False:
        return [SCALE_UNVERIFIED] * geom.n
    photo = isinstance(scale, dict)  # an estimated scale (photos): only wholly seen objects are measured
    out: list[str | None] = []
    for i, c in enumerate(geom.categories):
        partial = partly_seen(geom.frame.objects[i]) if photo else None
        if partial is not None:
            out.append(partial)
            continue
        size = (float(geom.width[i]), float(geom.width[i]), float(geom.height[i]))
        out.append(
            check_size(c, size, dims=("height", "extent"), tolerance=floor.size_tolerance, lower_bounds=("extent",))
        )
    return out


def apply_floor(geom: Any, floor: Floor) -> None:
    """Mark every object of the frame: `geom.in_view`, `geom.floor_why` (a below-floor object loses its answer
    point, hence its phrases: it stays in the scene as a distractor), `geom.metric_why`; counts go to
    `geom.cache["truth"]` (graph.meta["truth"])."""
    geom.cache["floor"] = floor
    counts: dict[str, int] = geom.cache.setdefault("truth", {})
    cam = geom.frame.camera
    geom.in_view = in_view_fractions(cam, [o.box for o in geom.frame.objects])
    geom.floor_why = floor_reasons(geom, floor)
    geom.metric_why = metric_reasons(geom, floor)
    for i, why in enumerate(geom.floor_why):
        if why is not None and geom.points[i] is not None:  # counted when the floor is what withholds it
            geom.points[i] = None
            counts[why] = counts.get(why, 0) + 1
    for why in geom.metric_why:
        if why is not None:
            key = f"no_metric_{why}"
            counts[key] = counts.get(key, 0) + 1
