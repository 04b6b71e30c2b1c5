"""Photo truth rules: claims a person could not check in a photo lifted to 3D from one view (audit round 2).

Read from the finished pair's record (each step's relation, the objects it reads and gives, every referring
phrase) and the frame; each withheld pair is counted by reason (sample.meta["truth"]); verify re-checks the
same rules by its own code (qa/verify_photo.py).

  position_contact_unseen   geometric depth places an object where its mask's bottom edge meets the ground;
                            when that edge is not the object's foot (provenance["position_unseen"]: the
                            mask is cut by the image border, the foot is at the bottom edge, it stands
                            behind an occluder, or it is a sink, mounted off the floor) its 3D position
                            and size are guesses: no depth order, distance, near/far, touching, between,
                            inside, 3D above/below or size relation involving it ("a foreground sink
                            farther than the toilet", COCO 111076 and 368402), also not through a phrase
                            ("the nearest X")
  size_same_category        a size comparison or size superlative between two objects of one category
                            ("the smallest bicycle", "broader than the second farthest bike"): on an
                            estimated-depth photo the lifted sizes of two similar objects are not
                            told apart by eye (462565, 515289, 384553)
  incomplete_category_claim the photo's annotations of the category may not be complete
                            (frame.meta["incomplete_categories"], from sources/image: crowd regions, many
                            instances, or listed): no phrase naming one of it ("the person" claims it is
                            the only one, "the leftmost person" its rank: 5802) and no set of the category
                            (filter: counts, superlatives, ordinals)
  size_horizontal_unseen    on an estimated-depth photo the lift knows an object's height and its apparent
                            width, not its extent along the view (every lifted footprint is square): no
                            width / length measurement and no wider / thinner comparison ("the longest
                            horizontal side of the nearest bicycle: 39 cm" for a bike seen head-on,
                            audit round 4, COCO 515289)
"""

from __future__ import annotations

from typing import Any

from refspatial_gen.core.model import Frame, QAPair

POSITION_RELATIONS = frozenset(
    {
        "front",
        "behind",
        "above_world",
        "below_world",
        "close",
        "far",
        "depth",
        "distance",
        "touching",
        "far_from",
        "next_to",
        "between",
        "inside",
        "outside",
    }
)
SIZE_RELATIONS = frozenset({"tall", "short", "big", "small", "wide", "thin"})
POSITION_WORDS = ("nearest", "farthest", "closest to", "farthest from")
SIZE_WORDS = ("tallest", "shortest", "biggest", "smallest")
HORIZONTAL_RELATIONS = frozenset({"wide", "thin", "width"})  # relations and measured quantities of a footprint
POSITION, SAME_SIZE, INCOMPLETE = "position_contact_unseen", "size_same_category", "incomplete_category_claim"
HORIZONTAL = "size_horizontal_unseen"


def contact_unseen(frame: Frame) -> dict[int, str]:
    """Objects of the photo without a trusted 3D position, with why (sources/image/contact.py recorded it)."""
    out: dict[int, str] = {}
    for o in frame.objects:
        why = (o.provenance or {}).get("position_unseen")
        if why:
            out[o.id] = str(why)
    return out


def estimated_photo(frame: Frame) -> bool:
    """A photo whose depth (hence every size) was estimated, not measured."""
    scale = frame.meta.get("metric_scale")
    return frame.source == "image" and isinstance(scale, dict) and scale.get("source") != "measured"


def _phrased(x: Any, out: list[tuple[str, int]]) -> list[tuple[str, int]]:
    if isinstance(x, dict):
        if isinstance(x.get("phrase"), str) and isinstance(x.get("object"), int):
            out.append((x["phrase"], int(x["object"])))
        for v in x.values():
            _phrased(v, out)
    elif isinstance(x, list):
        for v in x:
            _phrased(v, out)
    return out


def _ids(x: Any, outs: dict[str, Any], all_ids: list[int], acc: set[int]) -> set[int]:
    """Objects an argument or output holds; a step reference stands for that step's output."""
    if isinstance(x, bool) or x is None:
        return acc
    if isinstance(x, int):
        acc.add(x)
    elif x == "all":
        acc.update(all_ids)
    elif isinstance(x, dict):
        if set(x) == {"step"}:
            return _ids(outs.get(str(x["step"])), outs, all_ids, acc)
        for k, v in x.items():
            if k in ("object", "options", "anchor", "a", "b", "c", "of", "to", "in", "object_ids"):
                _ids(v, outs, all_ids, acc)
    elif isinstance(x, list):
        for v in x:
            _ids(v, outs, all_ids, acc)
    return acc


def _steps(qa: QAPair, all_ids: list[int]) -> list[tuple[str, str | None, set[int]]]:
    """(op, relation, objects it reads or gives) per program step."""
    outs: dict[str, Any] = {}
    rows = []
    for st in qa.program:
        args = st.get("args") or {}
        rel = args.get("relation") or args.get("quantity") or ("between" if st.get("op") == "between" else None)
        objs = _ids(args, outs, all_ids, set())
        _ids(st.get("out"), outs, all_ids, objs)
        outs[str(st.get("as"))] = st.get("out")
        rows.append((str(st.get("op")), rel if isinstance(rel, str) else None, objs))
    return rows


def photo_withhold(qa: QAPair, frame: Frame) -> str | None:
    """The reason this pair on a photo must not be emitted, or None (always None off photos)."""
    if frame.source != "image":
        return None
    cats = {o.id: o.category for o in frame.objects}
    all_ids = sorted(cats)
    unseen = contact_unseen(frame)
    sizes = estimated_photo(frame)
    incomplete = set((frame.meta.get("incomplete_categories") or {}).keys())
    for op, rel, objs in _steps(qa, all_ids):
        if unseen and (rel in POSITION_RELATIONS or rel in SIZE_RELATIONS) and not objs.isdisjoint(unseen):
            return POSITION
        if sizes and rel in HORIZONTAL_RELATIONS:
            return HORIZONTAL
        if sizes and rel in SIZE_RELATIONS:
            named = [cats[i] for i in objs if i in cats]
            if len(named) != len(set(named)):
                return SAME_SIZE
        if op == "filter" and incomplete and any(cats.get(i) in incomplete for i in objs):
            return INCOMPLETE
    for phrase, oid in _phrased([st.get("args") for st in qa.program], []):
        cat = cats.get(oid)
        if cat in incomplete:
            return INCOMPLETE
        kin = {i for i, c in cats.items() if c == cat}
        if (
            unseen
            and any(w in phrase for w in POSITION_WORDS)
            and not (kin | _anchor(phrase, frame)).isdisjoint(unseen)
        ):
            return POSITION
        if sizes and any(w in phrase.split() for w in SIZE_WORDS):
            return SAME_SIZE
    return None


def _anchor(phrase: str, frame: Frame) -> set[int]:
    """The objects the anchor of "X closest to / farthest from the Y" may mean (empty without one)."""
    for sep in (" closest to ", " farthest from "):
        if sep in phrase:
            from refspatial_gen.graph.resolve import resolve_phrase

            return set(resolve_phrase(phrase.split(sep, 1)[1], frame))
    return set()
