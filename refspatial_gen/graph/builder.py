"""build_graph(frame, config) -> SceneGraph: nodes with attributes, phrases and answer points, the
stored relation facts, free-space regions, and the meta (scale, thresholds, gravity) they rest on."""

from __future__ import annotations

from typing import Any

import numpy as np

from refspatial_gen.core.errors import DropUnit
from refspatial_gen.core.model import Frame, Node, SceneGraph
from refspatial_gen.graph.constants import thresholds_for
from refspatial_gen.graph.gravity import resolve_gravity
from refspatial_gen.graph.phrases import make_phrases
from refspatial_gen.graph.relations import all_facts
from refspatial_gen.graph.relations.orientation import horizontal_fronts
from refspatial_gen.graph.scene import SceneGeom
from refspatial_gen.graph.support import get_supports
from refspatial_gen.graph.visibility import Floor, apply_floor, floor_of

ROOM_OBJECT_SIZE = 0.8  # m: a frame with an object this large (or spread over ROOM_SPREAD) is a room
ROOM_SPREAD = 3.0
CONFIG_KEYS = {"scale", "thresholds", "free_space", "fit_gravity", "truth"}


def decide_scale(frame: Frame) -> str:
    """ "room" for furniture-sized objects or wide scenes, else "tabletop"."""
    if not frame.objects:
        return "tabletop"
    sizes = np.array([o.box.size for o in frame.objects])
    centres = np.array([o.box.center for o in frame.objects])
    spread = float(np.ptp(centres, axis=0).max()) if len(centres) > 1 else 0.0
    big = float(np.median(sizes.max(axis=1)))
    return "room" if big >= ROOM_OBJECT_SIZE or spread >= ROOM_SPREAD else "tabletop"


def geometry(frame: Frame, config: dict[str, Any] | None = None) -> SceneGeom:
    """The per-frame geometry the relations read (also used by tests and verification)."""
    config = dict(config or {})
    unknown = set(config) - CONFIG_KEYS
    if unknown:
        raise ValueError(f"unknown graph config key(s) {sorted(unknown)}; known: {sorted(CONFIG_KEYS)}")
    try:
        frame.validate()
    except ValueError as e:
        raise DropUnit("invalid_frame", str(e)) from e
    scale = config.get("scale") or decide_scale(frame)
    if scale not in ("tabletop", "room"):
        raise ValueError(f"graph scale must be 'tabletop' or 'room', not {scale!r}")
    th = thresholds_for(scale, frame.source, config.get("thresholds"))
    gravity = resolve_gravity(frame, fit_plane=bool(config.get("fit_gravity", True)))
    geom = SceneGeom(frame, th, gravity)
    geom.cache["scale"] = scale
    return geom


def _r(x: Any, nd: int = 3) -> Any:
    if isinstance(x, (list, tuple, np.ndarray)):
        return [_r(v, nd) for v in np.asarray(x, float).ravel()]
    return round(float(x), nd)


def _exact(x: Any) -> list[float]:
    """Full-precision values for attributes the relation tables decide on (sizes, between, sectors): the
    verifier decides on the geometry itself, so a rounded copy could fall on the other side of a margin."""
    return [float(v) for v in np.asarray(x, float).ravel()]


def _ordinals(values: np.ndarray, groups: dict[str, list[int]]) -> np.ndarray:
    """1-based rank of each object among its category by `values` (ascending)."""
    out = np.zeros(len(values), dtype=int)
    for members in groups.values():
        order = sorted(members, key=lambda i: (values[i], i))
        for r, i in enumerate(order):
            out[i] = r + 1
    return out


def make_nodes(geom: SceneGeom) -> list[Node]:
    phrases = make_phrases(geom)
    supports, roots = get_supports(geom)
    groups: dict[str, list[int]] = {}
    for i, c in enumerate(geom.categories):
        groups.setdefault(c, []).append(i)
    x_ord = _ordinals(geom.img_centroid[:, 0], groups)
    d_ord = _ordinals(geom.near_depth, groups)
    h_rank = _ordinals(-geom.height, groups)
    v_rank = _ordinals(-geom.volume, groups)
    hf = horizontal_fronts(geom)
    nodes = []
    for i in np.argsort(geom.ids, kind="stable"):
        o = geom.frame.objects[i]
        attrs = {
            "color": geom.colours[i],
            "color_from": geom.colour_how[i],
            "color_lab": None if geom.colour_lab[i] is None else list(geom.colour_lab[i]),
            "center": _exact(geom.centers[i]),
            "size": _r(geom.boxes[i].size, 4),
            "height": float(geom.height[i]),
            "width": float(geom.width[i]),
            "volume": float(geom.volume[i]),
            "img_xy": _r(geom.img_centroid[i], 4),
            "near_depth": _r(geom.near_depth[i]),
            "visible_px": int(geom.mask_area[i]),
            "x_ordinal": int(x_ord[i]),
            "depth_ordinal": int(d_ord[i]),
            "height_rank": int(h_rank[i]),
            "size_rank": int(v_rank[i]),
            "category_count": len(groups[o.category]),
            "front": _exact(hf[i]) if np.isfinite(hf[i]).all() else None,
            "surface": roots[i],
            "visible_fraction": round(float(o.visible_fraction), 4),
            "in_view": round(float(geom.in_view[i]), 4),
            "metric": geom.metric_why[i] is None,
        }
        if geom.floor_why[i] is not None:
            attrs["below_floor"] = geom.floor_why[i]
        if geom.metric_why[i] is not None:
            attrs["metric_check"] = geom.metric_why[i]
        if geom.cut_why[i] is not None:  # no size comparison or size value (qa/recognisable.py)
            attrs["sized"] = False
            attrs["size_check"] = geom.cut_why[i]
        if geom.front_why[i] is not None:  # its front is withheld: "front" is None
            attrs["front_check"] = geom.front_why[i]
        s = supports[i]
        pt = None if geom.points[i] is None else (float(geom.points[i][0]), float(geom.points[i][1]))
        nodes.append(Node(int(o.id), o.category, attrs, phrases[i], pt, None if s is None else s.label))
    return nodes


def build_graph(frame: Frame, config: dict[str, Any] | None = None) -> SceneGraph:
    """The metric scene graph of one frame (see the package docstring for what it holds)."""
    config = dict(config or {})
    geom = geometry(frame, config)
    return graph_from_geometry(geom, free_space=bool(config.get("free_space", True)), floor=floor_of(config))


def graph_from_geometry(geom: SceneGeom, free_space: bool = True, floor: Floor | None = None) -> SceneGraph:
    apply_floor(geom, floor or Floor())  # before the phrases: a below-floor object gets none
    nodes = make_nodes(geom)
    facts = all_facts(geom)
    regions = []
    if free_space and geom.world_ok:
        from refspatial_gen.graph.freespace import free_regions

        regions = free_regions(geom)
    from refspatial_gen.graph.relations.surface import surface_labels

    names = {s.id: (s.name or f"the {s.kind}") for s in geom.surfaces}
    surfaces = (
        {
            sid: {
                "z": round(float(e["z"]), 4),
                "name": names[sid],
                "corners": sorted(e["corners"]),
                "edges": sorted(e["edges"]),
            }
            for sid, e in surface_labels(geom).items()
        }
        if geom.world_ok
        else {}
    )
    meta = {
        "scale": geom.cache["scale"],
        "thresholds": geom.th.to_json(),
        "gravity": geom.gravity.to_json(),
        "world_relations": bool(geom.world_ok),
        "surfaces": surfaces,
        "source": geom.frame.source,
        "image_size": [geom.W, geom.H],
        "truth_floor": geom.cache["floor"].to_json(),
    }
    from refspatial_gen.graph.relations.between_angle import count_between

    count_between(geom)  # between is derived at question time; its new withholdings are counted here
    truth = dict(geom.cache["truth"])
    withheld = {"margin": "colour_unnamed_margin", "person_or_animal": "colour_withheld_person_or_animal"}
    for how in geom.colour_how:  # objects the colour namer left unnamed (run/stats.py truth_counts)
        if how in withheld:
            truth[withheld[how]] = truth.get(withheld[how], 0) + 1
    if truth:
        meta["truth"] = dict(sorted(truth.items()))
    return SceneGraph(geom.frame.frame_id, nodes, facts, regions, meta)
