"""An independent resolver for referring phrases: phrase + scene -> the ids of every object it could mean.

Why independent: a phrase generator that checks its own output proves nothing. This module parses the
phrase text and measures the scene itself (mask centroids, box corners through the camera, box heights
and volumes, sampled box-to-box distances, centre-over-footprint support), sharing only the threshold
values with the generator. Wherever two objects are within a tolerance (half the generator's margin) of
each other on the quantity a phrase ranks by, both are returned, so a phrase that is not robustly unique
resolves to several objects. Accepts a Frame (measures pixels and boxes) or a SceneGraph (reads the
measured node attributes and stored distances).
"""

from __future__ import annotations

import math
import re
from collections.abc import Callable
from dataclasses import dataclass
from typing import Any

import numpy as np

from refspatial_gen.core.geometry import Box3D, box_distance
from refspatial_gen.core.model import Frame, SceneGraph
from refspatial_gen.graph.phrases import DISPLAY_NAMES

SUPERLATIVES = {  # word -> (feature, pick the largest?)
    "tallest": ("height", True),
    "shortest": ("height", False),
    "biggest": ("volume", True),
    "smallest": ("volume", False),
    "leftmost": ("img_x", False),
    "rightmost": ("img_x", True),
    "nearest": ("near", False),
    "farthest": ("near", True),
}
ORDINALS = {"second": 2, "third": 3}
_REL = re.compile(r"^(?P<base>.+?) (?P<rel>closest to|farthest from|on) (?P<anchor>the .+)$")
_ORD_SIDE = re.compile(r"^(?P<ord>second|third) (?P<base>.+) from the (?P<side>left|right)$")
_ORD_DEPTH = re.compile(r"^(?P<ord>second|third) (?P<dir>nearest|farthest) (?P<base>.+)$")


@dataclass
class _Scene:
    ids: list[int]
    cats: list[str]
    colours: list[str | None]
    labs: list[Any]  # measured CIELAB colour per object (None: too few pixels or not measured)
    feats: dict[str, np.ndarray]  # img_x, near, height, volume
    tol: dict[str, float]
    surfaces: dict[str, tuple[float, Any]]  # name -> (top z, the surface box; None from a stored graph)
    dist: Callable[[int, int], float]
    on: Callable[[int, Any], bool]  # on(i, anchor) -> bool where anchor is ("obj", j) or ("surface", name)
    cdist: Callable[[int, int], float] | None = None  # box-centre distance (None: not known)


def _norm(cat: str) -> str:
    c = " ".join(cat.replace("_", " ").lower().split())
    return DISPLAY_NAMES.get(c, c)  # the names phrases use (data shared with the generator, like thresholds)


def _tolerances(th: dict[str, Any]) -> dict[str, float]:
    return {
        "img_x": th["image_margin"] / 4,
        "near": th["depth_margin"] / 2,
        "height_abs": th["height_margin_abs"] / 2,
        "height_rel": th["size_margin_rel"] / 2,
        "volume_rel": th["volume_margin_rel"] / 2,
        "dist": th["anchor_distance_margin"] / 2,
        "dist_rel": th.get("distance_margin_rel", 0.0) / 2,
        "colour_de": th.get("colour_min_delta_e", 20.0),  # no slack: both sides measure the same pixels
        "support_gap": th["support_gap"],
    }


def _from_frame(frame: Frame) -> _Scene:
    from refspatial_gen.graph.builder import decide_scale
    from refspatial_gen.graph.colour import colour_lab, colour_word, image_white, mask_pixels
    from refspatial_gen.graph.constants import thresholds_for
    from refspatial_gen.graph.gravity import resolve_gravity

    th = thresholds_for(decide_scale(frame), frame.source).to_json()
    G = resolve_gravity(frame).rotation
    cam = frame.camera
    boxes = [Box3D(G @ o.box.center, o.box.size, G @ o.box.rotation) for o in frame.objects]
    img_x, near, cols, labs = [], [], [], []
    white = image_white(frame.rgb)
    for o in frame.objects:
        m = o.mask.decode() if o.mask is not None else None
        if m is not None and m.any():
            img_x.append((np.nonzero(m)[1].mean() + 0.5) / cam.width)
            ys, xs = np.nonzero(m)  # the mask's bounding box, as the scene graph crops it
            crop = (slice(ys.min(), ys.max() + 1), slice(xs.min(), xs.max() + 1))
            px = mask_pixels(frame.rgb[crop], m[crop])
            labs.append(colour_lab(px, white))
            cols.append(
                colour_word(
                    px, o.attributes.get("color"), o.category, th["colour_min_share"], th["colour_margin"], white
                )[0]
            )
        else:
            uv, _ = cam.project(o.box.center[None])
            img_x.append((uv[0, 0] + 0.5) / cam.width)
            cols.append(None)
            labs.append(None)
        near.append(cam.world_to_cam(o.box.corners())[:, 2].min())
    feats = {
        "img_x": np.array(img_x),
        "near": np.array(near),
        "height": np.array([b.aabb()[1][2] - b.aabb()[0][2] for b in boxes]),
        "volume": np.array([float(np.prod(b.size)) for b in boxes]),
    }
    surfaces = {}
    for s in frame.surfaces:
        sb = Box3D(G @ s.box.center, s.box.size, G @ s.box.rotation)
        surfaces[(s.name or f"the {s.kind}").lower()] = (sb.top_z, sb)

    def dist(i: int, j: int) -> float:
        return box_distance(boxes[i], boxes[j], n=9)

    def on(i: int, anchor: Any) -> bool:
        bottom = boxes[i].aabb()[0][2]
        c = boxes[i].center
        if anchor[0] == "obj":
            j = anchor[1]
            top, sbox = boxes[j].aabb()[1][2], boxes[j]
        else:
            top, sbox = surfaces[anchor[1]]
        probe = np.array([[c[0], c[1], sbox.center[2]]])
        inside_xy = (
            bool(np.all(np.abs(sbox.to_local(probe)[0, :2]) <= sbox.size[:2] / 2 + 1e-9))
            if abs(sbox.rotation[2, 2]) > 0.99
            else bool(sbox.contains(probe)[0])
        )
        return abs(bottom - top) <= th["support_gap"] and inside_xy

    return _Scene(
        [o.id for o in frame.objects],
        [_norm(o.category) for o in frame.objects],
        cols,
        labs,
        feats,
        _tolerances(th),
        surfaces,
        dist,
        on,
        lambda i, j: float(np.linalg.norm(boxes[i].center - boxes[j].center)),
    )


def _from_graph(graph: SceneGraph) -> _Scene:
    th = graph.meta["thresholds"]
    nodes = sorted(graph.nodes, key=lambda n: n.object_id)
    ids = [n.object_id for n in nodes]
    pos = {k: i for i, k in enumerate(ids)}
    a = [n.attributes for n in nodes]
    feats = {
        "img_x": np.array([x["img_xy"][0] for x in a]),
        "near": np.array([x["near_depth"] for x in a]),
        "height": np.array([x["height"] for x in a]),
        "volume": np.array([x["volume"] for x in a]),
    }
    d = {}
    for f in graph.facts:
        if f.relation == "distance":
            d[(pos[f.args[0]], pos[f.args[1]])] = d[(pos[f.args[1]], pos[f.args[0]])] = f.value
    by_name = {str(e.get("name") or f"the {sid}").lower(): sid for sid, e in graph.meta.get("surfaces", {}).items()}
    sup = {pos[n.object_id]: n.support for n in nodes}

    def on(i: int, anchor: Any) -> bool:
        """Direct support as stored in the graph (the builder's support test)."""
        s = sup[i]
        if anchor[0] == "obj":
            return s == f"obj:{ids[anchor[1]]}"
        return s is not None and s == by_name.get(anchor[1])

    return _Scene(
        ids,
        [_norm(n.category) for n in nodes],
        [x.get("color") for x in a],
        [x.get("color_lab") for x in a],
        feats,
        _tolerances(th),
        {name: (0.0, None) for name in by_name},
        lambda i, j: d.get((i, j), np.inf),
        on,
        (lambda i, j: math.dist(a[i]["center"], a[j]["center"])) if all("center" in x for x in a) else None,
    )


class _Unresolved(list):  # type: ignore[type-arg]
    """Every object of the category: a colour word that does not set its objects apart means any of them."""


def _base(sc: _Scene, text: str) -> list[int] | None:
    """Objects matching "[colour] category"; None when the text is not such a phrase. A colour word counts
    only when every other object of the category has its own colour word and a colour at least
    `colour_min_delta_e` away (CIE76) from each matching object; else every object of the category
    (`_Unresolved`: the phrase fits them all)."""
    cats = set(sc.cats)
    if text in cats:
        return [i for i in range(len(sc.ids)) if sc.cats[i] == text]
    head, _, rest = text.partition(" ")
    if rest not in cats:
        return None
    same = [i for i in range(len(sc.ids)) if sc.cats[i] == rest]
    hit = [i for i in same if sc.colours[i] == head]
    if not hit:
        return hit
    for j in same:
        if j in hit:
            continue
        if sc.colours[j] is None or sc.labs[j] is None or any(sc.labs[i] is None for i in hit):
            return _Unresolved(same)
        lj = np.asarray(sc.labs[j], float)
        if min(float(np.linalg.norm(np.asarray(sc.labs[i], float) - lj)) for i in hit) < sc.tol["colour_de"]:
            return _Unresolved(same)
    return hit


def _within(values: np.ndarray, target: float, tol: np.ndarray | float) -> np.ndarray:
    return np.abs(values - target) <= tol


def _tol(sc: _Scene, feat: str, v: np.ndarray, ref: float) -> np.ndarray:
    if feat == "height":
        return np.maximum(sc.tol["height_abs"], sc.tol["height_rel"] * np.maximum(v, ref))
    if feat == "volume":
        return sc.tol["volume_rel"] * np.maximum(v, ref)
    return np.full(len(v), sc.tol[feat])


def _superlative(sc: _Scene, members: list[int], feat: str, largest: bool, rank: int = 1) -> list[int]:
    if len(members) < rank:
        return []
    v = sc.feats[feat][members]
    order = np.argsort(-v if largest else v, kind="stable")
    target = v[order[rank - 1]]
    close = _within(v, target, _tol(sc, feat, v, target))
    return [members[k] for k in np.flatnonzero(close)]


def _nearest_set(
    dist: Callable[[int, int], float], members: list[int], a: int, closest: bool, tols: dict[str, float]
) -> set[int]:
    """Positions in `members` within the generator's gap (absolute and relative) of the nearest (farthest)."""
    d = np.array([dist(i, a) for i in members])
    if not len(d):
        return set()
    target = d.min() if closest else d.max()
    tol = np.maximum(tols["dist"], tols["dist_rel"] * np.maximum(d, target))
    return {int(k) for k in np.flatnonzero(_within(d, target, tol))}


def _resolve(sc: _Scene, phrase: str) -> list[int]:
    p = " ".join(phrase.lower().split())
    if not p.startswith("the "):
        return []
    body = p[4:]
    m = _REL.match(body)
    if m and (members := _base(sc, m["base"])) is not None:
        if isinstance(members, _Unresolved):
            return list(members)
        anchor_text = m["anchor"]
        if m["rel"] == "on" and anchor_text in sc.surfaces:
            return [i for i in members if sc.on(i, ("surface", anchor_text))]
        anchors = _resolve(sc, anchor_text)
        if len(anchors) != 1:
            return []
        a = anchors[0]
        members = [i for i in members if i != a]
        if m["rel"] == "on":
            return [i for i in members if sc.on(i, ("obj", a))]
        if any(sc.on(i, ("obj", a)) or sc.on(a, ("obj", i)) for i in members):
            return members  # one stands on the anchor (or carries it): 0 m apart says nothing, the phrase fits all
        keep = _nearest_set(sc.dist, members, a, m["rel"] == "closest to", sc.tol)
        if sc.cdist is not None:  # the centres must single out the same object (where a person sees them)
            keep |= _nearest_set(sc.cdist, members, a, m["rel"] == "closest to", sc.tol)
        return [members[k] for k in sorted(keep)]
    m = _ORD_SIDE.match(body)
    if m and (base := _base(sc, m["base"])) is not None:
        if isinstance(base, _Unresolved):
            return list(base)
        return _superlative(sc, base, "img_x", m["side"] == "right", ORDINALS[m["ord"]])
    m = _ORD_DEPTH.match(body)
    if m and (base := _base(sc, m["base"])) is not None:
        if isinstance(base, _Unresolved):
            return list(base)
        return _superlative(sc, base, "near", m["dir"] == "farthest", ORDINALS[m["ord"]])
    head, _, rest = body.partition(" ")
    if head in SUPERLATIVES and (base := _base(sc, rest)) is not None:
        if isinstance(base, _Unresolved):
            return list(base)
        feat, largest = SUPERLATIVES[head]
        return _superlative(sc, base, feat, largest)
    members = _base(sc, body)
    return [] if members is None else members


def resolve_phrase(phrase: str, frame_or_graph: Frame | SceneGraph) -> list[int]:
    """Ids of every object the phrase could refer to (exactly one for a good referring phrase)."""
    sc = _from_frame(frame_or_graph) if isinstance(frame_or_graph, Frame) else _from_graph(frame_or_graph)
    return sorted(sc.ids[i] for i in _resolve(sc, phrase))


def resolver(frame_or_graph: Frame | SceneGraph) -> Callable[[str], list[int]]:
    """A resolve function bound to one scene (measures the scene once; for checking many phrases)."""
    sc = _from_frame(frame_or_graph) if isinstance(frame_or_graph, Frame) else _from_graph(frame_or_graph)
    return lambda phrase: sorted(sc.ids[i] for i in _resolve(sc, phrase))
