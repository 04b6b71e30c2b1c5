"""verify's own re-check of the truth floors (not the generator's filter: graph/visibility.py, qa/faint.py).

From what a shard stores, for every object a QA pair names (program arguments and outputs, targets, options,
marks, key steps):
  - visible pixels counted from its decoded mask, the source's visible fraction, and the share of its 3D box
    inside the image (a 5x5x5 lattice on the box's faces and inside, projected through the camera) against the
    floor the graph recorded (graph.meta["truth_floor"], the recipe's `graph: truth:`);
  - every referring phrase resolved by the independent resolver on the frame as stored and on the frame
    without the objects below the floor: a phrase that names the object in one and not the other fails;
  - for a metric value or a size comparison: the stored box against its category's size range
    (truth/sizes.py) and the frame's metric scale;
  - recognisability (graph/visibility.py): a visible mask that is no sliver (largest inscribed disc, by an exact
    Euclidean distance transform, against the recorded thickness floor); no size question about an object whose
    mask reaches the border or whose box is not whole in view, and no camera turn to face such a target;
    contrast with its surroundings, and a dark object's size and detail (qa/verify_contrast.py, its own CIELAB
    and ring); a front (Orientation key steps, stored fronts of named objects) only on uncut objects seen at
    least `min_front_visible_fraction`;
  - free-space answer points: `min_point_clearance_px` from the image border and every object's mask but the
    surface's own, and `free_clearance` from every obstacle footprint on the plane (its own ray and footprints).
"""

from __future__ import annotations

from dataclasses import replace
from typing import Any

import numpy as np

from refspatial_gen.core.model import Frame, QAPair, SceneGraph
from refspatial_gen.qa.verify_contrast import low_contrast
from refspatial_gen.truth.sizes import check_size

METRIC_RELATIONS = ("distance", "depth", "tall", "short", "big", "small", "wide", "thin")
SIZE_RELATIONS = ("tall", "short", "big", "small", "wide", "thin")
ROTATION_RELATIONS = ("rotation_horizontal", "rotation_vertical")  # a camera turn faces a target seen whole
FRONT_RELATIONS = ("angle", "facing", "facing_away", "obj_front", "obj_left", "obj_behind", "obj_right")
THICK_TOL = 0.05  # px: two exact distance transforms
CLEAR_TOL_PX = 0.5  # px: the generator measures from the pixel grid, this check from the pixel centre
CLEAR_TOL_M = 0.001  # m
IN_VIEW_TOL = 0.07  # lattice error bound of the generator's (<= 1/(2*12)) plus this one's (<= 1/(2*20))
_LATTICE = 20


def named_objects(qa: QAPair) -> set[int]:
    """Every object id the pair's record names (ints under object-valued keys, outputs of object steps)."""
    out: set[int] = set(int(t) for t in qa.targets)

    def walk(x: Any, key: str = "") -> None:
        if isinstance(x, dict):
            for k, v in x.items():
                walk(v, k)
        elif isinstance(x, list):
            for v in x:
                walk(v, key)
        elif isinstance(x, int) and not isinstance(x, bool) and key in _OBJECT_KEYS:
            out.add(int(x))

    for st in qa.program:
        walk(st.get("args") or {})
        o = st.get("out")
        if isinstance(o, int) and not isinstance(o, bool):  # a superlative's / ordinal's object
            out.add(int(o))
        elif isinstance(o, dict):  # a located object, a choice's options
            walk(o)
        elif st.get("op") == "mark" and isinstance(o, list):  # the marked objects
            walk(o, "object_ids")
    s = qa.answer_struct or {}
    walk({k: v for k, v in s.items() if k in ("object_ids", "option_ids", "marks", "object_id")})
    return out


_OBJECT_KEYS = {"object", "object_ids", "option_ids", "object_id", "options"}


def _box_in_view(frame: Frame, box: Any) -> float:
    t = (np.arange(_LATTICE) + 0.5) / _LATTICE - 0.5  # cell centres: an unbiased share (end points are not)
    g = np.stack(np.meshgrid(t, t, t, indexing="ij"), -1).reshape(-1, 3) * np.asarray(box.size, float)
    world = np.asarray(box.center, float) + g @ np.asarray(box.rotation, float).T
    uv, z = frame.camera.project(world)
    cam = frame.camera
    ok = (z > 1e-3) & (uv[:, 0] >= 0) & (uv[:, 0] < cam.width) & (uv[:, 1] >= 0) & (uv[:, 1] < cam.height)
    return float(ok.mean())


def _photo(frame: Frame) -> bool:
    return isinstance((frame.meta or {}).get("metric_scale"), dict)  # an estimated scale: a photo


def _pixels(frame: Frame) -> int:
    return int(frame.camera.width * frame.camera.height)


def _below_floor_once(frame: Frame, floor: dict[str, Any]) -> dict[int, str]:
    """below_floor, computed once per stored frame and floor (verify checks every pair of a frame against the
    same objects; the contrast re-check reads the image, too slow to repeat per pair)."""
    key = repr(sorted(floor.items()))
    cache = frame.__dict__.setdefault("_verify_below_floor", {})
    if key not in cache:
        cache[key] = below_floor(frame, floor)
    return dict(cache[key])


def below_floor(frame: Frame, floor: dict[str, Any]) -> dict[int, str]:
    """Objects of the stored frame under the recorded floor, with why (recomputed from masks and boxes)."""
    out: dict[int, str] = {}
    for o in frame.objects:
        px = 0 if o.mask is None else int(o.mask.decode().sum())
        if px < int(floor.get("min_visible_px", 0)):
            out[o.id] = f"{px} visible pixels < {floor['min_visible_px']}"
        elif _photo(frame) and px < float(floor.get("min_photo_area_fraction", 0.0)) * _pixels(frame):
            out[o.id] = f"{px / _pixels(frame):.4f} of the photo < {floor['min_photo_area_fraction']}"
        elif float(o.visible_fraction) < float(floor.get("min_visible_fraction", 0.0)):
            out[o.id] = f"visible fraction {o.visible_fraction:.3f} < {floor['min_visible_fraction']}"
        elif _box_in_view(frame, o.box) < float(floor.get("min_in_view_fraction", 0.0)) - IN_VIEW_TOL:
            out[o.id] = f"{_box_in_view(frame, o.box):.2f} of its box in view < {floor['min_in_view_fraction']}"
        elif (why := _sliver(frame, o, floor) or low_contrast(frame, o, floor)) is not None:
            out[o.id] = why
    return out


_SUPERLATIVES = {"tallest", "shortest", "biggest", "smallest", "largest", "widest", "thinnest"}


def _names_size_superlative(question: str, category: str) -> bool:
    """A size superlative word followed by the category's words, with at most one word (a colour) between."""
    words = [w.strip(".,?!;:()[]\"'") for w in question.lower().split()]
    cat = category.replace("_", " ").lower().split()
    for k, w in enumerate(words):
        if w in _SUPERLATIVES:
            for skip in (1, 2):
                if words[k + skip : k + skip + len(cat)] == cat:
                    return True
    return False


def _scale(frame: Frame) -> float:
    return float(np.sqrt(frame.camera.width * frame.camera.height / 307200.0))  # lengths are for 640x480


def _sliver(frame: Frame, o: Any, floor: dict[str, Any]) -> str | None:
    """Why the object's visible mask is a sliver (thin in pixels and much thinner than the object), or None."""
    from scipy.ndimage import binary_closing, distance_transform_edt

    n_px = float(floor.get("min_thickness_px", 0.0)) * _scale(frame)
    ratio = float(floor.get("min_thickness_ratio", 0.0))
    if n_px <= 0 or ratio <= 0 or o.mask is None:
        return None
    side = 2 * int(np.ceil(n_px)) + 1  # closed first: gaps a viewer bridges (graph/visibility.closing_side)
    m = binary_closing(np.pad(o.mask.decode(), side), structure=np.ones((side, side), bool))
    r = float(distance_transform_edt(np.pad(m, 1)).max())
    _, z = frame.camera.project(np.asarray(o.box.center, float)[None])
    cam = frame.camera
    half = np.inf if z[0] <= 1e-3 else (cam.fx + cam.fy) / 4.0 * float(np.median(o.box.size)) / float(z[0])
    if r < n_px - THICK_TOL and r < ratio * half - THICK_TOL:
        return f"a sliver: inscribed radius {r:.2f} px < {n_px:.2f} px and < {ratio} x {half:.1f} px"
    return None


def _cut(frame: Frame, o: Any, floor: dict[str, Any]) -> str | None:
    """Why the object counts as cut by the image border (its mask reaches it, or its box is not whole in view)."""
    H, W = frame.camera.height, frame.camera.width
    ys, xs = np.nonzero(o.mask.decode()) if o.mask is not None else (np.zeros(0), np.zeros(0))
    if len(xs) and (xs.min() <= 2 or ys.min() <= 2 or xs.max() >= W - 3 or ys.max() >= H - 3):
        return "its mask reaches the image border"
    share = _box_in_view(frame, o.box)
    if share < float(floor.get("min_whole_in_view", 0.0)) - IN_VIEW_TOL:
        return f"only {share:.2f} of its box is in view"
    return None


def program_phrases(qa: QAPair) -> list[tuple[str, int]]:
    """Every (referring phrase, object id) the program's step arguments hold, sorted, once each."""
    out = []

    def walk(x: Any) -> None:
        if isinstance(x, dict):
            if "phrase" in x and isinstance(x.get("object"), int):
                out.append((str(x["phrase"]), int(x["object"])))
            for v in x.values():
                walk(v)
        elif isinstance(x, list):
            for v in x:
                walk(v)

    for st in qa.program:
        walk(st.get("args") or {})
    return sorted(set(out))


def _size(box: Any) -> tuple[float, float, float]:
    """(larger, smaller horizontal extent, height) of a stored box, from its rotated corners (z up)."""
    c = np.asarray(box.corners(), float)
    R = np.asarray(box.rotation, float)
    s = np.asarray(box.size, float)
    h = float(c[:, 2].max() - c[:, 2].min())
    horiz = sorted(float(np.hypot(*(R[:2, k] * s[k]))) for k in range(3) if abs(R[2, k]) < 0.99)
    w = horiz[-1] if horiz else float(max(s))
    return w, w, h


def check_truth(qa: QAPair, frames: dict[str, Frame], graphs: dict[str, SceneGraph]) -> list[str]:
    """Reasons the pair breaks a truth floor (empty when it passes)."""
    if qa.family == "point_depth" or not qa.frame_ids:
        return []
    out: list[str] = []
    fid = qa.frame_ids[0]
    frame, graph = frames[fid], graphs[fid]
    floor = graph.meta.get("truth_floor")
    if not isinstance(floor, dict):
        return []  # written before the floors existed
    objs = {o.id: o for o in frame.objects}
    named = {i for i in named_objects(qa) if i in objs}
    low = _below_floor_once(frame, floor)
    for i in sorted(named & set(low)):
        out.append(f"names object {i} ({objs[i].category}) below the visibility floor: {low[i]}")
    if low:
        out += _phrase_changes(qa, frame, set(low))
    if not set(METRIC_RELATIONS).isdisjoint(qa.relations):
        out += _metric(qa, frame, named, objs, float(floor.get("size_tolerance", 0.0)))
    if not set(SIZE_RELATIONS).isdisjoint(qa.relations):
        for i in sorted(named):
            if (why := _cut(frame, objs[i], floor)) is not None:
                out.append(f"size question names object {i} ({objs[i].category}): {why}")
    if not set(ROTATION_RELATIONS).isdisjoint(qa.relations):
        for i in sorted(set(qa.targets) & set(objs)):
            if (why := _cut(frame, objs[i], floor)) is not None:
                out.append(f"a camera turn to face object {i} ({objs[i].category}): {why}")
    for o in frame.objects:
        if _names_size_superlative(qa.question, o.category) and (why := _cut(frame, o, floor)) is not None:
            out.append(f"a size superlative of {o.category!r} while object {o.id} of it is cut: {why}")
    if not set(FRONT_RELATIONS).isdisjoint(qa.relations):
        out += _fronts(qa, frame, graph, named, floor)
    if "free_space" in qa.relations:
        out += _clearance(qa, frame, graph, floor)
    return out


def _fronts(qa: QAPair, frame: Frame, graph: SceneGraph, named: set[int], floor: dict[str, Any]) -> list[str]:
    """Every object whose front the pair reads (its Orientation key steps; named objects with a stored front)
    must be uncut and seen at least `min_front_visible_fraction`."""
    objs = {o.id: o for o in frame.objects}
    by_phrase = {p: n.object_id for n in graph.nodes for p in n.phrases}
    nodes = {n.object_id: n for n in graph.nodes}
    used = {i for i in named if i in nodes and nodes[i].attributes.get("front") is not None}
    for ks in qa.key_steps:
        if ks.type == "Orientation":
            used |= {by_phrase[ks.phrase]} if ks.phrase in by_phrase else {int(t) for t in qa.targets}
    out = []
    need = float(floor.get("min_front_visible_fraction", 0.0))
    for i in sorted(used & set(objs)):
        o = objs[i]
        why = _cut(frame, o, floor)
        if why is None and float(o.visible_fraction) < need:
            why = f"visible fraction {o.visible_fraction:.3f} < {need}"
        if why is None and (flat := _flatness(o.box)) < float(floor.get("min_front_height_ratio", 0.0)):
            why = f"lying flat: height / smaller horizontal extent {flat:.2f} < {floor['min_front_height_ratio']}"
        if why is not None:
            out.append(f"orientation question reads the front of object {i} ({o.category}): {why}")
    return out


def _flatness(box: Any) -> float:
    """Height over the smaller side of the minimum-area rectangle around the box's corners seen from above."""
    import cv2

    c = np.asarray(box.corners(), float)
    (_, (a, b), _) = cv2.minAreaRect(c[:, :2].astype(np.float32))
    return float(np.ptp(c[:, 2]) / max(min(a, b), 1e-9))


def _phrase_changes(qa: QAPair, frame: Frame, low: set[int]) -> list[str]:
    from refspatial_gen.graph.resolve import resolve_phrase

    seen = replace(frame, objects=[o for o in frame.objects if o.id not in low])
    out = []
    for phrase, oid in program_phrases(qa):
        full = resolve_phrase(phrase, frame)
        if list(full) != [oid]:
            continue  # the graph-based phrase check (verify.py) judges uniqueness
        if list(resolve_phrase(phrase, seen)) != [oid]:
            out.append(f"phrase {phrase!r} names object {oid} only when objects below the floor {sorted(low)} count")
    return out


def _metric(qa: QAPair, frame: Frame, named: set[int], objs: dict[int, Any], tol: float) -> list[str]:
    scale = frame.meta.get("metric_scale")
    if isinstance(scale, dict) and scale.get("reliable") is False:
        return [
            f"metric or size question ({sorted(set(METRIC_RELATIONS) & set(qa.relations))}) on a frame "
            "whose metric scale is unverified"
        ]
    out = []
    H, W = frame.camera.height, frame.camera.width
    for i in sorted(named):
        o = objs[i]
        if isinstance(scale, dict):  # a photo: the object must be wholly seen (graph/visibility.partly_seen)
            ys, xs = np.nonzero(o.mask.decode()) if o.mask is not None else (np.zeros(0), np.zeros(0))
            if len(xs) and (xs.min() <= 2 or ys.min() <= 2 or xs.max() >= W - 3 or ys.max() >= H - 3):
                out.append(f"metric or size question names object {i} ({o.category}): its mask reaches the border")
                continue
            if (o.provenance or {}).get("behind") or str((o.provenance or {}).get("contact", "")).startswith("behind"):
                out.append(f"metric or size question names object {i} ({o.category}): it stands behind an occluder")
                continue
        why = check_size(
            o.category, _size(o.box), dims=("height", "extent"), tolerance=tol + 0.02, lower_bounds=("extent",)
        )
        if why is not None:
            out.append(f"metric or size question names object {i} ({o.category}): {why}")
    return out


def _clearance(qa: QAPair, frame: Frame, graph: SceneGraph, floor: dict[str, Any]) -> list[str]:
    """A free-space answer point keeps `min_point_clearance_px` (scaled) from the image border and from every
    object's mask but its surface's own object, and `free_clearance` from every obstacle footprint there."""
    s = qa.answer_struct or {}
    region = s.get("region")
    need_px = float(floor.get("min_point_clearance_px", 0.0)) * _scale(frame)
    if not isinstance(region, dict) or need_px <= 0:
        return []
    cam = frame.camera
    W, H = cam.width, cam.height
    surf = next((x for x in frame.surfaces if x.id == region.get("surface_id")), None)
    own = None if surf is None else surf.object_id
    out = []
    for pt in s.get("points") or []:
        u, v = min(W - 1, max(0, int(pt[0] * W))), min(H - 1, max(0, int(pt[1] * H)))
        if min(u, v, W - 1 - u, H - 1 - v) < need_px - CLEAR_TOL_PX:
            out.append(f"free-space point {pt} is {min(u, v, W - 1 - u, H - 1 - v)} px from the image border")
        for o in frame.objects:
            if o.id == own or o.mask is None:
                continue
            ys, xs = np.nonzero(o.mask.decode())
            if len(xs) and float(np.hypot(xs - u, ys - v).min()) < need_px - CLEAR_TOL_PX:
                out.append(f"free-space point {pt} is within {need_px:.1f} px of object {o.id}'s mask")
        out += _plane_clearance(frame, graph, float(region["z"]), u, v)
    return out


def _plane_clearance(frame: Frame, graph: SceneGraph, z: float, u: int, v: int) -> list[str]:
    """The ray through pixel (u, v) meets the plane z at a point `free_clearance` clear of every obstacle."""
    import shapely

    th = graph.meta.get("thresholds") or {}
    clear, gap = float(th.get("free_clearance", 0.0)), float(th.get("support_gap", 0.05))
    G = np.array((graph.meta.get("gravity") or {}).get("rotation", np.eye(3)), float)
    cam = frame.camera
    R, o = G @ cam.world_from_cam[:3, :3], G @ cam.world_from_cam[:3, 3]
    d = R @ np.array([(u + 0.5 - cam.cx) / cam.fx, (v + 0.5 - cam.cy) / cam.fy, 1.0])
    if abs(d[2]) < 1e-12 or (z - o[2]) / d[2] <= 0:
        return [f"pixel ({u}, {v}) does not see the plane z={z:.3f}"]
    hit = o + (z - o[2]) / d[2] * d
    out = []
    for ob in frame.objects:
        c = np.asarray(ob.box.corners(), float) @ G.T
        if not (c[:, 2].min() <= z + gap and c[:, 2].max() > z + 0.005):
            continue
        foot = _footprint(G @ np.asarray(ob.box.rotation, float), np.asarray(ob.box.size, float), c)
        dist = float(shapely.distance(shapely.Point(hit[:2]), foot))
        if dist < clear - CLEAR_TOL_M:
            out.append(f"free-space point is {dist:.3f} m from object {ob.id}'s footprint (< {clear} m)")
    return out


def _footprint(R: np.ndarray, size: np.ndarray, corners: np.ndarray) -> Any:
    """A box's footprint on the ground plane: the base of a vertical prism (an axis within 2 degrees of
    vertical), else the convex hull of its corners (never larger than the generator's rectangle around them)."""
    import shapely

    k = int(np.argmax(np.abs(R[2])))
    centre = corners.mean(axis=0)[:2]
    if abs(R[2, k]) >= np.cos(np.deg2rad(2.0)):
        a, b = (R[:2, j] * size[j] / 2 for j in range(3) if j != k)
        return shapely.Polygon([centre - a - b, centre + a - b, centre + a + b, centre - a + b])
    return shapely.convex_hull(shapely.MultiPoint(corners[:, :2]))
