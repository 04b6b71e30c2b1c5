"""Named thresholds of every relation, with a tabletop and a room preset.

Why: every decision in the graph rests on a comparison with a margin; the margin is where a relation is
undecided and must not be asked about. Values start from the RefSpatial authors' published choices and
are scaled to the scene (a tabletop wants centimetres, a room decimetres). A recipe may override any
field through the graph config (`thresholds: {name: value}`).
"""

from __future__ import annotations

from dataclasses import asdict, dataclass, fields, replace
from typing import Any


@dataclass(frozen=True)
class Thresholds:
    # camera / image directions
    lateral_margin: float  # m, camera-x difference of centres for left/right
    depth_margin: float  # m, nearest-face depth difference for front/behind
    image_margin: float  # fraction of image height/width, for above/below (image)
    vertical_margin: float  # m, centre height difference for above/below (world)
    stack_tolerance: float  # m, "A's bottom at B's top" counts as above/on within this
    # sizes (a comparison needs the larger to exceed the smaller by max(abs, rel * larger))
    height_margin_abs: float  # m
    size_margin_rel: float  # fraction, for height and width
    volume_margin_rel: float  # fraction, for volume
    width_margin_abs: float  # m
    # distances
    distance_margin: float  # m, close/far difference of surface distances
    touch_distance: float  # m, touching below this ...
    touch_band: float  # m, ... not touching above touch_distance + touch_band
    next_to_distance: float  # m
    far_from_distance: float  # m
    far_from_band: float  # m, undecided within +- this of far_from_distance
    quantity_tolerance: float  # fraction, accepted relative error of a metric answer
    # containment / between
    inside_fraction: float  # > this fraction of A's volume inside B's box = inside
    inside_band: float  # undecided within +- this of inside_fraction
    between_t_margin: float  # fraction of the B-C segment kept clear at each end (t in (m, 1 - m) is between)
    between_corridor: float  # distance from the B-C line, as a fraction of |BC|, below which A is on the segment
    # orientation
    rotation_margin: float  # rad, below this the turn direction is undecided
    facing_cone: float  # rad, half-angle of the facing cone
    facing_margin: float  # rad
    angle_margin: float  # rad, angle between fronts: reported tolerance
    sector_margin: float  # rad, object-frame 90-degree sectors: undecided within this of a boundary
    # support surfaces
    support_gap: float  # m, a support's top within this of the object's bottom
    support_overlap: float  # fraction of the object's footprint over the surface
    corner_reach: float  # m, object within this of a surface corner
    edge_band: float  # m, object within this of a surface edge
    surface_band_margin: float  # m, corner/edge undecided band
    # free space
    free_radius_min: float  # m
    free_min_area: float  # m^2
    free_clearance: float  # m, obstacle footprints grown by this
    free_grid: float  # m, sampling step for visibility
    visibility_tolerance: float  # m, depth agreement with the depth map
    corner_size: float  # m, side of a corner free region
    edge_width: float  # m, width of an edge free region
    # phrases
    anchor_distance_margin: float  # m, "closest to the X" must win by this
    # colour words (graph/colour.py): the winning term's share of the lit pixels, and its lead over the
    # runner-up; below either the object gets no colour word (counted as colour_unnamed_margin)
    colour_min_share: float = 0.5
    colour_margin: float = 0.2
    # a colour word names an object only when every other object of its category has a confident, different
    # word AND a colour at least this far in CIELAB (CIE76; graph/phrases.py, graph/resolve.py)
    colour_min_delta_e: float = 20.0
    # between (graph/relations/containment.py): undecided bands outside the decided region, so "not
    # between" is only said clearly off the segment (t < m - band, t > 1 - m + band, or off by corridor + band)
    between_t_band: float = 0.10
    between_corridor_band: float = 0.15
    # the corridor narrows linearly within this share of |BC| of either anchor (a lens, not a rectangle): a can
    # just past one anchor and off to its side is not "between" (audit round 3)
    between_taper: float = 0.30
    # seen from each anchor, the direction to A within this angle (rad, 22 deg) of the direction to the other
    # anchor, in the ground plane and the image; beyond it by the band (10 deg) A is clearly not between; and
    # A's box at least this share of |BC| from both anchors' boxes (graph/relations/between_angle.py, audit
    # round 4: a box 40 deg off the line at 20% of the way, a bottle just beside one anchor)
    between_max_angle: float = 0.384
    between_angle_band: float = 0.175
    between_anchor_gap: float = 0.08
    # near/far (left/right) edge of a surface only when the surface's extent along the edge normal is at least
    # this many edge bands: on a shallow shelf every object is near both edges (audit round 3)
    edge_depth_factor: float = 3.0
    # clear margins a person can see (audit round 2: relations decided on differences too small to see).
    # left/right and above/below in the image: the mask centroids must be apart by this fraction of the image
    # side (width for left/right, height for above/below) ...
    image_clear_margin: float = 0.05
    # ... and by this share of the narrower mask's width (left/right) or the shorter mask's height (above/below):
    # a tray lying in front of two others and overlapping both is neither left nor right of them
    image_extent_share: float = 0.5
    # ... and neither mask may reach this fraction of the image side past BOTH ends of the other (a train spanning
    # the photo behind a cyclist; a night stand at the end of the bed stays decided: graph/relations/span.py)
    image_span_margin: float = 0.05
    # front/behind (nearest-face depths): the farther must exceed the nearer by this fraction of the farther,
    # on top of depth_margin
    depth_margin_rel: float = 0.10
    # close/far to an anchor: the larger surface distance must exceed the smaller by this fraction of the larger,
    # on top of distance_margin
    distance_margin_rel: float = 0.20
    # above/below (world) beside, not over (graph/relations/vertical_clear.py): with footprints overlapping by
    # less than this share (of either footprint), A's bottom must clear B's top by max(clear_margin, clear_share
    # x B's height): a mouse on a thin book beside a tray is not "above" it (pre-audit round 5)
    vertical_over_share: float = 0.15
    vertical_clear_margin: float = 0.10
    vertical_clear_share: float = 0.5
    # corner and edge names of a surface only where a person sees them at the top face's real extent
    # (graph/surface_seen.py, audit round 4): the share of a corner square / edge band the depth map shows
    # (the plane, or an object standing there) must reach these ...
    min_corner_seen: float = 0.5
    min_edge_seen: float = 0.5
    # ... and no named edge where the plane goes on past it: the depth map shows the plane on more than this
    # share of the seen samples in a band `extent_band` (m) wide just outside the edge
    max_extent_continuation: float = 0.5
    extent_band: float = 0.10
    extent_height_tolerance: float = 0.012  # m, what the depth map shows there lies this close to the plane
    # a surface is named (free space, corners, edges) only when a person sees its top (graph/surface_visible.py,
    # audit round 5): the depth map shows its plane on this many pixels and this many rows deep (median column),
    # both for a 640x480 image (scaled by the image area / height)
    min_surface_px: float = 2000.0  # audit round 5: a shelf seen on 1359 px was not recognisable
    min_surface_rows: float = 12.0
    # inside (graph/relations/receptacle.py): A fits in B only when A's largest horizontal extent is at most
    # this many times B's (a pencil may stick out of a cup a little; a table never fits in a bin)
    inside_max_overhang: float = 1.2
    # a corner / edge free region's answer point at most this share of the surface's extent from its corner
    # along each side, or from its edge across the surface (graph/corner_point.py, audit round 5)
    corner_point_max_share: float = 0.25

    def to_json(self) -> dict[str, float]:
        return {k: round(float(v), 6) for k, v in sorted(asdict(self).items())}


TABLETOP = Thresholds(
    lateral_margin=0.02,
    depth_margin=0.02,
    image_margin=0.02,
    vertical_margin=0.03,
    stack_tolerance=0.01,
    height_margin_abs=0.01,
    size_margin_rel=0.30,
    volume_margin_rel=0.50,
    width_margin_abs=0.01,
    distance_margin=0.02,
    touch_distance=0.01,
    touch_band=0.01,
    next_to_distance=0.08,
    far_from_distance=0.30,
    far_from_band=0.10,
    quantity_tolerance=0.15,
    inside_fraction=0.30,
    inside_band=0.10,
    between_t_margin=0.15,
    between_corridor=0.25,
    rotation_margin=0.035,
    facing_cone=0.5236,
    facing_margin=0.0873,
    angle_margin=0.0873,
    sector_margin=0.1745,
    support_gap=0.05,
    support_overlap=0.70,
    corner_reach=0.15,
    edge_band=0.08,
    surface_band_margin=0.03,
    free_radius_min=0.20,
    free_min_area=0.03,
    free_clearance=0.01,
    free_grid=0.015,
    visibility_tolerance=0.025,
    corner_size=0.20,
    edge_width=0.10,
    anchor_distance_margin=0.03,
)

ROOM = Thresholds(
    lateral_margin=0.10,
    depth_margin=0.10,
    image_margin=0.02,
    vertical_margin=0.10,
    stack_tolerance=0.05,
    height_margin_abs=0.05,
    size_margin_rel=0.30,
    volume_margin_rel=0.50,
    width_margin_abs=0.05,
    distance_margin=0.10,
    touch_distance=0.05,
    touch_band=0.05,
    next_to_distance=0.50,
    far_from_distance=2.00,
    far_from_band=0.50,
    quantity_tolerance=0.15,
    inside_fraction=0.30,
    inside_band=0.10,
    between_t_margin=0.15,
    between_corridor=0.25,
    rotation_margin=0.035,
    facing_cone=0.5236,
    facing_margin=0.0873,
    angle_margin=0.0873,
    sector_margin=0.1745,
    support_gap=0.10,
    support_overlap=0.50,
    corner_reach=0.50,
    edge_band=0.30,
    surface_band_margin=0.10,
    free_radius_min=0.50,
    free_min_area=0.10,
    free_clearance=0.05,
    free_grid=0.04,
    visibility_tolerance=0.025,
    corner_size=0.60,
    edge_width=0.30,
    anchor_distance_margin=0.10,
)

# Sources whose boxes come from noisy reconstructions: contact is only known to within centimetres
# (the RefSpatial authors used 10 cm on CA-1M scans).
NOISY_SOURCES = ("scan", "image")
NOISY_TOUCH_DISTANCE = 0.05
NOISY_TOUCH_BAND = 0.05

PRESETS = {"tabletop": TABLETOP, "room": ROOM}

# Photos (the image source): sizes, depths and distances come from a single-view lift (a fitted camera height
# or a depth model), good to tens of percent, so every comparison of them needs a wider clear margin (audit
# round 2: two adult bicycles lifted 0.856 vs 0.863 m "thinnest"; bicycles 9.8 and 10.0 m away ordered;
# elephants "smaller"). Raised to at least these values; a recipe override of a field still wins.
PHOTO_SOURCES = ("image",)
PHOTO_FLOORS = {
    "size_margin_rel": 0.40,  # the larger at least 1.67x the smaller (height, width)
    "volume_margin_rel": 0.65,  # volumes: about 3x
    "depth_margin_rel": 0.20,  # the farther at least 1.25x the nearer
    "distance_margin_rel": 0.30,  # close/far to an anchor: 1.43x
    "far_from_band": 0.75,  # rooms: "far" beyond 2.75 m, "not far" within 1.25 m
}


def thresholds_for(scale: str, source: str, overrides: dict[str, Any] | None = None) -> Thresholds:
    """The preset for `scale`, adjusted for the source's noise (photos: PHOTO_FLOORS), with recipe overrides
    applied (a graph stores every field, so building from its stored values gives the same thresholds)."""
    t = PRESETS[scale]
    if source.split(":")[0] in PHOTO_SOURCES:
        t = replace(t, **{k: max(getattr(t, k), v) for k, v in PHOTO_FLOORS.items()})
    if source.split(":")[0] in NOISY_SOURCES:
        t = replace(
            t,
            touch_distance=max(t.touch_distance, NOISY_TOUCH_DISTANCE),
            touch_band=max(t.touch_band, NOISY_TOUCH_BAND),
        )
    if overrides:
        names = {f.name for f in fields(Thresholds)}
        bad = sorted(set(overrides) - names)
        if bad:
            raise ValueError(f"unknown threshold(s) {bad}; known: {sorted(names)}")
        t = replace(t, **{k: float(v) for k, v in overrides.items()})
    return t
