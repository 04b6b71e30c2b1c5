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

Recognisability (audit round 2: a book seen as a sliver under another, edge-on picture frames, a toy car cut
by the border asked which way it faces): besides the pixel floor, an object needs half of itself seen and a
visible mask that is not a sliver of something that is not thin itself (`below_floor_thin`); an object cut by
the image border gets no size comparison or size value (`sized: False`, withheld by qa/recognisable.py) and
no front (`front: None`), and a front also needs the object mostly seen (`min_front_visible_fraction`).

Recipe (`graph: truth:`, every key optional; docs/quality.md has the measurements behind the defaults;
pixel lengths are for a 640x480 image and scale with sqrt(width * height / (640 * 480))):
  min_visible_px             visible mask pixels an object needs (default 150)
  min_visible_fraction       visible / unoccluded projected pixels, where the source knows it (default 0.5)
  min_photo_area_fraction    on photos (an estimated metric scale, no occlusion estimate): visible mask pixels
                             over the image's pixels an object needs (default 0.004: a toilet glimpsed as a
                             sliver behind a door frame, a chair seen through a far doorway; audit round 3)
  min_in_view_fraction       share of the object's 3D box inside the camera's view (default 0.5)
  min_thickness_px           a mask whose largest inscribed disc has a smaller radius (default 6 px) ...
  min_thickness_ratio        ... and under this share of the half-size its middle box extent projects to
                             (default 0.25) is a sliver: edge-on frames pass the pixel count, pens do not fail
  min_whole_in_view          an object with less of its box in view, or a mask reaching the border, is cut:
                             no size question, no front (default 0.9)
  min_front_visible_fraction a front (facing, angle) needs this visible fraction (default 0.7)
  min_front_height_ratio     a front also needs the object's height at least this share of its smaller horizontal
                             extent (default 0.4): a book or notebook lying flat has no facing a person can
                             judge (its spine points along the table; audit round 3). Measured: books <= 0.28,
                             notebooks 0.07, scissors 0.11; every other object with a front >= 0.52
  min_point_clearance_px     free-space answer points keep this far from every object's mask and from the
                             image border (default 20 px; graph/freespace.py)
  size_tolerance             widen every category size range by this fraction (default 0.0)
  min_contrast_delta_e, dark_lightness, min_dark_px, min_dark_detail, dark_silhouette_delta_e
                             the contrast floor (graph/contrast.py: can a person make the object out)
  lookalike_stand_ins        1 (default): every object gets faint stand-ins of the categories a person could take
                             it for (truth/lookalikes.py, run/pipeline.py); 0: off
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

import numpy as np

from refspatial_gen.core.errors import RecipeError
from refspatial_gen.graph.contrast import CONTRAST_DEFAULTS, CONTRAST_DOCS, contrast_reasons
from refspatial_gen.schema import Field, check_section

DEFAULTS: dict[str, float] = {
    "min_visible_px": 150,
    "min_visible_fraction": 0.5,
    "min_in_view_fraction": 0.5,
    "min_photo_area_fraction": 0.004,
    "min_thickness_px": 6.0,
    "min_thickness_ratio": 0.25,
    "min_whole_in_view": 0.9,
    "min_front_visible_fraction": 0.7,
    "min_front_height_ratio": 0.4,
    "min_point_clearance_px": 20.0,
    "size_tolerance": 0.0,
    **CONTRAST_DEFAULTS,
    "lookalike_stand_ins": 1,
}
_DOCS = {
    "min_visible_px": (int, 1_000_000, "visible mask pixels every referent, option and mark needs"),
    "min_visible_fraction": (float, 1.0, "visible / unoccluded projected pixels (where the source measures it)"),
    "min_photo_area_fraction": (float, 1.0, "photos: visible mask pixels / image pixels every referent needs"),
    "min_in_view_fraction": (float, 1.0, "share of the object's 3D box inside the camera's view (image border cut)"),
    "min_thickness_px": (
        float,
        1000.0,
        "largest inscribed disc radius (px at 640x480) below which a mask may be a sliver",
    ),
    "min_thickness_ratio": (
        float,
        1.0,
        "... when also under this share of the half-size its middle extent projects to",
    ),
    "min_whole_in_view": (float, 1.0, "box share in view below which (or a mask at the border) an object is cut"),
    "min_front_visible_fraction": (float, 1.0, "visible fraction an object needs for its front (facing, angle)"),
    "min_front_height_ratio": (float, 100.0, "height / smaller horizontal extent an object needs for its front"),
    "min_point_clearance_px": (
        float,
        1000.0,
        "free-space point distance (px at 640x480) from every mask and the border",
    ),
    "size_tolerance": (float, 10.0, "widen every category size range by this fraction before a metric question"),
    **CONTRAST_DOCS,
    "lookalike_stand_ins": (int, 1, "1: faint stand-ins of look-alike categories count (truth/lookalikes.py)"),
}
TRUTH_FIELDS: dict[str, Field] = {
    k: Field(t, default=DEFAULTS[k], min=0.0 if t is float else 0, max=mx, doc=doc) for k, (t, mx, doc) in _DOCS.items()
}
# reasons (graph.meta["truth"] keys, node attribute "below_floor")
FEW_PIXELS, LOW_FRACTION, OUT_OF_VIEW = "below_floor_pixels", "below_floor_fraction", "below_floor_border"
PHOTO_SMALL = "below_floor_photo_area"  # photos: too small a share of the image to make out
THIN = "below_floor_thin"  # the visible mask is a sliver of an object that is not thin itself
SCALE_UNVERIFIED = "metric_scale_unverified"
CUT_BY_BORDER = "cut_by_border"  # the mask reaches the image border (or the box is not whole in view)
OCCLUDED = "occluded_in_front"  # photos: another object in front hides part of it (its foot)
FRONT_CUT, FRONT_HIDDEN = "front_withheld_cut_by_border", "front_withheld_hidden"
FRONT_LYING = "front_withheld_lying"  # lying flat (a book, a notebook): no facing a person can judge
SIZE_CUT = "no_size_cut_by_border"  # graph.meta["truth"]: objects asked no size question (node: sized False)
BORDER_PX = 3  # mask pixels in the outer BORDER_PX rows/columns (within 2 px of the edge) touch the border
GRID = 12  # points per box axis for the in-view share (share error <= 1/24 for a border cut)


@dataclass(frozen=True)
class Floor:
    min_visible_px: int = int(DEFAULTS["min_visible_px"])
    min_visible_fraction: float = DEFAULTS["min_visible_fraction"]
    min_in_view_fraction: float = DEFAULTS["min_in_view_fraction"]
    size_tolerance: float = DEFAULTS["size_tolerance"]
    min_thickness_px: float = DEFAULTS["min_thickness_px"]
    min_thickness_ratio: float = DEFAULTS["min_thickness_ratio"]
    min_whole_in_view: float = DEFAULTS["min_whole_in_view"]
    min_front_visible_fraction: float = DEFAULTS["min_front_visible_fraction"]
    min_point_clearance_px: float = DEFAULTS["min_point_clearance_px"]
    min_photo_area_fraction: float = DEFAULTS["min_photo_area_fraction"]
    min_front_height_ratio: float = DEFAULTS["min_front_height_ratio"]
    min_contrast_delta_e: float = DEFAULTS["min_contrast_delta_e"]
    dark_lightness: float = DEFAULTS["dark_lightness"]
    min_dark_px: float = DEFAULTS["min_dark_px"]
    min_dark_detail: float = DEFAULTS["min_dark_detail"]
    dark_silhouette_delta_e: float = DEFAULTS["dark_silhouette_delta_e"]
    lookalike_stand_ins: int = int(DEFAULTS["lookalike_stand_ins"])

    def to_json(self) -> dict[str, float]:
        """Stored as graph.meta["truth_floor"]: verify (qa/verify_truth.py) re-checks against it."""
        out = {k: round(float(getattr(self, k)), 6) for k in sorted(TRUTH_FIELDS)}
        out["min_visible_px"] = int(self.min_visible_px)
        out["lookalike_stand_ins"] = int(self.lookalike_stand_ins)
        return out


def floor_of(config: dict[str, Any] | None) -> Floor:
    """The floor from a graph config's `truth` mapping (already checked by `check_truth_section`)."""
    raw = dict((config or {}).get("truth") or {})
    unknown = set(raw) - set(TRUTH_FIELDS)
    if unknown:
        raise ValueError(f"unknown graph.truth key(s) {sorted(unknown)}; known: {sorted(TRUTH_FIELDS)}")
    vals = {k: (raw[k] if raw.get(k) is not None else f.default) for k, f in TRUTH_FIELDS.items()}
    ints = ("min_visible_px", "lookalike_stand_ins")
    floats = {k: float(v) for k, v in vals.items() if k not in ints}
    return Floor(int(vals["min_visible_px"]), lookalike_stand_ins=int(vals["lookalike_stand_ins"]), **floats)


def px_scale(width: int, height: int) -> float:
    """Pixel lengths of the recipe are for a 640x480 image: this factor scales them to the frame's size."""
    return float(np.sqrt(width * height / (640.0 * 480.0)))


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


def touches_border(mask: np.ndarray) -> bool:
    """Does a full-frame mask reach the image border (within BORDER_PX)?"""
    b = BORDER_PX
    return bool(mask[:b].any() or mask[-b:].any() or mask[:, :b].any() or mask[:, -b:].any())


def closing_side(floor: Floor, scale: float) -> int:
    """Side (px) of the square that closes a mask before its thickness is measured: gaps narrower than the
    thickness floor are what a viewer bridges (a scan's mask scattered over a lamp), a solid strip stays thin."""
    return 2 * int(np.ceil(floor.min_thickness_px * scale)) + 1


def inscribed_radius(mask: np.ndarray, side: int = 1) -> float:
    """Radius (px) of the largest disc inside the mask, after closing it with a `side` x `side` square: how
    thick its thickest part is (0 for no mask)."""
    import cv2

    rows, cols = np.flatnonzero(mask.any(axis=1)), np.flatnonzero(mask.any(axis=0))
    if not len(rows):
        return 0.0
    crop: np.ndarray = np.pad(mask[rows[0] : rows[-1] + 1, cols[0] : cols[-1] + 1].astype(np.uint8), side)
    if side > 1:
        crop = np.asarray(cv2.morphologyEx(crop, cv2.MORPH_CLOSE, np.ones((side, side), np.uint8)))
    return float(cv2.distanceTransform(crop, cv2.DIST_L2, cv2.DIST_MASK_PRECISE).max())


def projected_half_thickness(camera: Any, box: Any) -> float:
    """Half the length (px) the box's middle extent projects to at its centre's depth: how thick the object
    would look seen broadside (a pen: its own thinness; a picture frame: its height). inf behind the camera."""
    z = float(camera.world_to_cam(np.asarray(box.center, float)[None])[0, 2])
    if z <= 1e-3:
        return float("inf")
    mid = float(sorted(float(v) for v in box.size)[1])
    return 0.5 * 0.5 * (camera.fx + camera.fy) * mid / z


def is_sliver(radius: float, half: float, floor: Floor, scale: float) -> bool:
    """Thin in the image (radius under min_thickness_px, scaled) and much thinner than the object itself."""
    return radius < floor.min_thickness_px * scale and radius < floor.min_thickness_ratio * half


def is_photo(frame: Any) -> bool:
    """A photo: its metric scale is estimated (a dict in frame.meta), and no source measures occlusion, so
    every object reports visible_fraction 1.0 and only its share of the image says whether it can be made out."""
    return isinstance(frame.meta.get("metric_scale"), dict)


def floor_reasons(geom: Any, floor: Floor, masks: list[np.ndarray | None]) -> list[str | None]:
    """Per object position: why it is below the visibility floor, or None."""
    out: list[str | None] = []
    cam = geom.frame.camera
    scale = px_scale(cam.width, cam.height)
    photo_px = floor.min_photo_area_fraction * cam.width * cam.height if is_photo(geom.frame) else 0.0
    for i, o in enumerate(geom.frame.objects):
        m = masks[i]
        if int(geom.mask_area[i]) < floor.min_visible_px or m is None:
            out.append(FEW_PIXELS)
        elif int(geom.mask_area[i]) < photo_px:
            out.append(PHOTO_SMALL)
        elif float(o.visible_fraction) < floor.min_visible_fraction:
            out.append(LOW_FRACTION)
        elif geom.in_view[i] < floor.min_in_view_fraction:
            out.append(OUT_OF_VIEW)
        elif is_sliver(
            inscribed_radius(m, closing_side(floor, scale)), projected_half_thickness(cam, o.box), floor, scale
        ):
            out.append(THIN)
        else:
            out.append(None)
    return out


def cut_reasons(geom: Any, floor: Floor, masks: list[np.ndarray | None]) -> list[str | None]:
    """Per object position: CUT_BY_BORDER when its mask reaches the image border or less than
    `min_whole_in_view` of its box is in view (its size and its front cannot be judged), else None."""
    return [
        CUT_BY_BORDER if (m is not None and touches_border(m)) or geom.in_view[i] < floor.min_whole_in_view else None
        for i, m in enumerate(masks)
    ]


def front_reasons(geom: Any, floor: Floor, cut: list[str | None]) -> list[str | None]:
    """Per object position with a front: why its front is withheld (cut by the border, less than
    `min_front_visible_fraction` seen: a toy car's front cannot be told from its back; or lying flat, its
    height under `min_front_height_ratio` of its smaller horizontal extent: a book's spine), or None."""
    out: list[str | None] = []
    fp = np.asarray(geom.footprints, float).reshape(-1, 4, 2)
    smaller = np.minimum(np.linalg.norm(fp[:, 1] - fp[:, 0], axis=1), np.linalg.norm(fp[:, 2] - fp[:, 1], axis=1))
    for i, o in enumerate(geom.frame.objects):
        if not geom.has_front[i]:
            out.append(None)
        elif cut[i] is not None:
            out.append(FRONT_CUT)
        elif float(o.visible_fraction) < floor.min_front_visible_fraction:
            out.append(FRONT_HIDDEN)
        elif float(geom.height[i]) < floor.min_front_height_ratio * float(smaller[i]):
            out.append(FRONT_LYING)
        else:
            out.append(None)
    return out


def partly_seen(obj: Any) -> str | None:
    """Why a photo's object is only partly seen, or None: its mask touches the image border (within
    BORDER_PX) or the depth estimator found it standing behind another object that hides its foot. Its
    lifted box is then a piece of the object (a bench cut by the frame judged smaller than an oven, an
    elephant half under water 1.11 m tall: audit, issue 15), so no size or metric claim rests on it."""
    if obj.mask is not None and obj.mask.area and touches_border(obj.mask.decode()):
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
    point, hence its phrases: it stays in the scene as a distractor), `geom.metric_why`, `geom.cut_why`
    (no size question), `geom.front_why` (its front is taken away, so every orientation relation reading it
    is undecided); counts go to `geom.cache["truth"]` (graph.meta["truth"])."""
    geom.cache["floor"] = floor
    counts: dict[str, int] = geom.cache.setdefault("truth", {})
    cam = geom.frame.camera
    masks = [o.mask.decode() if o.mask is not None and o.mask.area else None for o in geom.frame.objects]
    geom.in_view = in_view_fractions(cam, [o.box for o in geom.frame.objects])
    geom.floor_why = contrast_reasons(geom, floor, masks, floor_reasons(geom, floor, masks))
    geom.metric_why = metric_reasons(geom, floor)
    geom.cut_why = cut_reasons(geom, floor, masks)
    geom.front_why = front_reasons(geom, floor, geom.cut_why)

    def count(key: str) -> None:
        counts[key] = counts.get(key, 0) + 1

    for i, why in enumerate(geom.floor_why):
        if why is not None and geom.points[i] is not None:  # counted when the floor is what withholds it
            geom.points[i] = None
            count(why)
    for why in geom.metric_why:
        if why is not None:
            count(f"no_metric_{why}")
    for i, why in enumerate(geom.cut_why):
        if why is not None and geom.floor_why[i] is None and geom.metric_why[i] is None:
            count(SIZE_CUT)  # counted where this rule is what withholds the size questions
    for i, why in enumerate(geom.front_why):
        if why is not None:
            geom.fronts[i] = np.nan
            geom.has_front[i] = False
            if geom.floor_why[i] is None:
                count(why)
