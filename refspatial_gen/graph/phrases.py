"""Unique referring phrases for every object that can have one, shortest first.

Forms (the grammar `resolve.py` parses independently):
  the {cat} | the {colour} {cat}
  the {tallest|shortest|biggest|smallest|leftmost|rightmost|nearest|farthest} [{colour}] {cat}
  the {second|third} [{colour}] {cat} from the {left|right}
  the {second|third} {nearest|farthest} [{colour}] {cat}
  the [{colour}] {cat} {closest to|farthest from|on} {anchor phrase}
A phrase is emitted only when the decisions behind it are decided (outside every margin) against every
other object it could be confused with; objects of the same category are the candidates, including
objects that are hidden (they are still in the scene).
"""

from __future__ import annotations

from typing import Any

import numpy as np

from refspatial_gen.graph.colour import delta_e
from refspatial_gen.graph.relations import directions, sizes
from refspatial_gen.graph.relations.common import FALSE, TRUE
from refspatial_gen.graph.relations.containment import _inside
from refspatial_gen.graph.scene import SceneGeom
from refspatial_gen.graph.support import get_supports

ORDINAL_WORDS = {2: "second", 3: "third"}
MAX_PHRASES = 8
ANCHORED_WORDS = (" closest to ", " farthest from ", " on ")  # phrases that name the object through another


def anchored(phrase: str) -> bool:
    """True for a phrase that names its object through another object or surface ("the basket closest to
    the orange", "the cup on the tray"): inside another phrase's relative clause it nests a second clause."""
    p = f" {phrase} "
    return any(w in p for w in ANCHORED_WORDS)


# categories whose own name is a word the questions use for something else: "the camera" is also the viewpoint
# ("closest to the camera", "from the camera"), so the simulated catalog's camera is called a photo camera
# wherever a question or phrase names it (graph/resolve.py parses the same names)
DISPLAY_NAMES = {"camera": "photo camera"}


def display_category(cat: str) -> str:
    """The category as questions and phrases name it."""
    c = " ".join(cat.replace("_", " ").lower().split())
    return DISPLAY_NAMES.get(c, c)


def _extreme(codes: np.ndarray, i: int, group: list[int]) -> bool:
    """i beats every other member of the group (codes[i, j] == TRUE for all j)."""
    return all(codes[i, j] == TRUE for j in group if j != i)


def _rank(codes: np.ndarray, i: int, group: list[int]) -> int | None:
    """1-based rank of i when every comparison with the group is decided (codes[j, i] TRUE = j ahead)."""
    ahead = 0
    for j in group:
        if j == i:
            continue
        c = codes[i, j]
        if c == TRUE:
            continue
        if c == FALSE and codes[j, i] == TRUE:
            ahead += 1
            continue
        return None
    return ahead + 1


def _same_rank(codes: np.ndarray, i: int, group: list[int], seen: list[int], r: int) -> tuple[bool, bool]:
    """(rank from the start, rank from the end) of i are the same among the objects a viewer can see as among
    all of them: an ordinal must not count an object too small or hidden to notice."""
    if len(seen) == len(group):
        return True, True
    rs = _rank(codes, i, seen) if i in seen else None
    if rs is None:
        return False, False
    return rs == r, len(seen) - rs == len(group) - r


def _group_phrases(geom: SceneGeom, group: list[int], noun: str, out: dict[int, list[tuple[int, str]]]) -> None:
    """Superlatives and ordinals within `group` (all sharing `noun`, e.g. "red cup")."""
    if len(group) < 2:
        return
    lc = directions.matrices(geom, "left")[1]
    fc = directions.matrices(geom, "front")[1]
    xs = geom.cam_centers[group, 0]
    ds = geom.near_depth[group]
    lateral_first = np.ptp(xs) >= np.ptp(ds)  # the axis of largest spread gets priority
    pri_x, pri_d = (0, 1) if lateral_first else (1, 0)
    seen = [j for j in group if geom.points[j] is not None]  # what a viewer can see (graph/visibility.py)
    for i in group:
        if geom.world_ok:
            tc, bc = sizes._tall(geom)[1], sizes._big(geom)[1]
            if _extreme(tc, i, group):
                out[i].append((2, f"the tallest {noun}"))
            if _extreme(tc.T, i, group):
                out[i].append((2, f"the shortest {noun}"))
            if _extreme(bc, i, group):
                out[i].append((2, f"the biggest {noun}"))
            if _extreme(bc.T, i, group):
                out[i].append((2, f"the smallest {noun}"))
        r = _rank(lc, i, group)
        if r is not None:
            k = len(group)
            fwd, back = _same_rank(lc, i, group, seen, r)
            if r == 1:
                out[i].append((pri_x, f"the leftmost {noun}"))
            if r == k:
                out[i].append((pri_x, f"the rightmost {noun}"))
            if k >= 3 and r in ORDINAL_WORDS and r != k and fwd:
                out[i].append((pri_x, f"the {ORDINAL_WORDS[r]} {noun} from the left"))
            if k >= 3 and (k - r + 1) in ORDINAL_WORDS and r != 1 and back:
                out[i].append((pri_x, f"the {ORDINAL_WORDS[k - r + 1]} {noun} from the right"))
        r = _rank(fc, i, group)
        if r is not None:
            k = len(group)
            fwd, back = _same_rank(fc, i, group, seen, r)
            if r == 1:
                out[i].append((pri_d, f"the nearest {noun}"))
            if r == k:
                out[i].append((pri_d, f"the farthest {noun}"))
            if k >= 3 and r in ORDINAL_WORDS and r != k and fwd:
                out[i].append((pri_d, f"the {ORDINAL_WORDS[r]} nearest {noun}"))
            if k >= 3 and (k - r + 1) in ORDINAL_WORDS and r != 1 and back:
                out[i].append((pri_d, f"the {ORDINAL_WORDS[k - r + 1]} farthest {noun}"))


def colour_sets_apart(geom: SceneGeom, sub: list[int], members: list[int]) -> str | None:
    """Whether the colour word shared by `sub` singles them out among `members` (same category, hidden and
    faint ones included: a viewer may still see them), or why not: every other member needs a confident
    colour word of its own ("colour_phrase_other_unnamed"; round 2: a tan basket was "the brown basket" because
    the obviously brown one was below the namer's margin) that is also far in CIELAB from every member of
    `sub` ("colour_phrase_too_close": beige vs brown, white vs light gray), and `sub` its measured colours."""
    cols, labs = geom.colours, geom.colour_lab
    if any(labs[i] is None for i in sub):
        return "colour_phrase_other_unnamed"
    for j in members:
        if j in sub:
            continue
        if cols[j] is None or labs[j] is None:
            return "colour_phrase_other_unnamed"
        if any(delta_e(labs[i], labs[j]) < geom.th.colour_min_delta_e for i in sub):  # type: ignore[arg-type]
            return "colour_phrase_too_close"
    return None


def make_phrases(geom: SceneGeom) -> list[list[str]]:
    """Phrases per object position, shortest first (ties: axis of largest spread, then alphabetical)."""
    n = geom.n
    cats = [display_category(c) for c in geom.categories]
    cols = geom.colours
    out: dict[int, list[tuple[int, str]]] = {i: [] for i in range(n)}
    by_cat: dict[str, list[int]] = {}
    for i in range(n):
        by_cat.setdefault(cats[i], []).append(i)
    simple: dict[int, str] = {}  # anchor phrases (visible objects only): category or colour + category
    truth = geom.cache.setdefault("truth", {})
    for cat, members in sorted(by_cat.items()):
        if len(members) == 1:
            out[members[0]].append((0, f"the {cat}"))
            if geom.points[members[0]] is not None:
                simple[members[0]] = f"the {cat}"
        for col in sorted({c for c in (cols[i] for i in members) if c is not None}):
            sub = [i for i in members if cols[i] == col]
            why = colour_sets_apart(geom, sub, members)
            if why is not None:
                lost = sum(geom.points[i] is not None for i in sub)  # visible objects that lose the word
                if len(members) > 1 and lost:  # a lone object needs no colour word: not counted
                    truth[why] = truth.get(why, 0) + lost
                continue
            if len(sub) == 1:
                i = sub[0]
                out[i].append((0, f"the {col} {cat}"))
                if geom.points[i] is not None:
                    simple.setdefault(i, f"the {col} {cat}")
            elif len(sub) < len(members):  # "the leftmost brown basket" when every basket is brown: a false contrast
                _group_phrases(geom, sub, f"{col} {cat}", out)
        _group_phrases(geom, members, cat, out)
    _anchor_phrases(geom, by_cat, cats, simple, out)
    result = []
    for i in range(n):
        seen, items = set(), []
        for _pri, p in sorted(out[i], key=lambda t: (len(t[1].split()), t[0], t[1])):
            if p not in seen:
                seen.add(p)
                items.append(p)
        # an object the image does not show gets no phrase (it still counts as a distractor above)
        result.append(items[:MAX_PHRASES] if geom.points[i] is not None else [])
    return result


def _stands_on(supports: list[Any], geom: SceneGeom, i: int, j: int) -> bool:
    s = supports[i]
    return s is not None and s.kind == "object" and geom.index[int(s.ref)] == j


def _anchor_phrases(
    geom: SceneGeom,
    by_cat: dict[str, list[int]],
    cats: list[str],
    simple: dict[int, str],
    out: dict[int, list[tuple[int, str]]],
) -> None:
    if not geom.world_ok:
        return
    d, c = geom.surface_distance, geom.center_distance
    m = geom.th.anchor_distance_margin
    rel = geom.th.distance_margin_rel  # the winner must also beat the runner-up by this share (a visible gap)
    supports, _ = get_supports(geom)
    inside = _inside(geom)[1]
    surf_names = {s.id: (s.name or f"the {s.kind}") for s in geom.surfaces}
    for cat, members in sorted(by_cat.items()):
        if len(members) < 2:
            continue
        for a in sorted(simple):
            if cats[a] == cat:
                continue
            if any(_stands_on(supports, geom, x, a) or _stands_on(supports, geom, a, x) for x in members) or any(
                inside[x, a] != FALSE or inside[a, x] != FALSE for x in members
            ):
                continue  # a member on the anchor (or carrying it) is 0 m from it: no distance a person sees
            da, ca = d[members, a], c[members, a]
            for k, i in enumerate(members):
                others, oc = np.delete(da, k), np.delete(ca, k)
                lo, hi = float(others.min()), float(others.max())
                clo, chi = float(oc.min()), float(oc.max())
                # the centres must agree by the same gaps (a person judges by where the objects are)
                if da[k] + max(m, rel * lo) < lo and ca[k] + max(m, rel * clo) < clo:
                    out[i].append((3, f"the {cat} closest to {simple[a]}"))
                if da[k] - max(m, rel * da[k]) > hi and ca[k] - max(m, rel * ca[k]) > chi:
                    out[i].append((3, f"the {cat} farthest from {simple[a]}"))
        for i in members:
            s = supports[i]
            if s is None:
                continue
            if s.kind == "object":
                j = geom.index[int(s.ref)]
                if j not in simple:
                    continue
                anchor = simple[j]
                # every other member must be clearly off that object
                near = [
                    o
                    for o in members
                    if o != i
                    and (geom.footprint_overlap[o, j] > 0 or geom.footprint_overlap[j, o] > 0)
                    and abs(geom.lo[o, 2] - geom.hi[j, 2]) <= 2 * geom.th.support_gap
                ]
            else:
                anchor = surf_names[str(s.ref)]
                near = [
                    o
                    for o in members
                    if o != i and ((so := supports[o]) is None or so.ref == s.ref or so.kind == "object")
                ]
            if not near:
                out[i].append((3, f"the {cat} on {anchor}"))
