"""Key steps of a QA pair: one perceptual step per object the reasoning looks at (Position, Size,
Orientation), in program order, then the answer; the reasoning trace is rendered from them.

Why per op: which objects a step looks at, and what of them (a size comparison needs their sizes, a facing
question the anchor's orientation, a measurement its own quantity), is the op's and the relation's
business: every step contributes the positions of its object arguments, and its op adds the rest
(Op.key_steps); relations say what must be perceived (Relation.key_step).
"""

from __future__ import annotations

from typing import Any, NamedTuple

from refspatial_gen.core.model import KeyStep
from refspatial_gen.graph.relations import REGISTRY
from refspatial_gen.graph.relations.sizes import DERIVED
from refspatial_gen.qa.index import Reject, SceneIndex
from refspatial_gen.qa.ops.base import FREE_KINDS, Op
from refspatial_gen.qa.program import Step, Template
from refspatial_gen.qa.render import LETTERS, round_key
from refspatial_gen.qa.values import PointValue

_RELATIONS = REGISTRY.loaded  # id -> Relation


class KeyPlan(NamedTuple):
    """What key steps read of one step, resolved at compile time."""

    step: Step
    rel_literal: Any  # the relation when the program fixes it
    rel_slot: str | None  # the slot/step holding the relation otherwise
    single: tuple[str, ...]  # env names of single-object arguments (anchor, a, b, of, to), in that order
    lists: tuple[str, ...]  # env names inside list arguments (anchors, options)
    extra: Any  # the op's own plan (Op.key_extra)
    own: bool  # the op adds key steps of its own (overrides Op.key_steps)


def plan_keys(t: Template) -> tuple[KeyPlan, ...]:
    out = []
    for st in t.steps:
        a = st.args
        r = a.get("relation")
        lit = r.value if r is not None and r.kind == "literal" else None
        slot = r.value if r is not None and r.kind != "literal" else None
        single = tuple(
            a[k].value
            for k in ("anchor", "a", "b", "of", "to")
            if a.get(k) is not None and a[k].kind in ("slot", "step")
        )
        lists = tuple(
            x.value for k in ("anchors", "options") if a.get(k) is not None and a[k].kind == "list" for x in a[k].value
        )
        own = type(st.impl).key_steps is not Op.key_steps
        out.append(KeyPlan(st, lit, slot, single, lists, st.impl.key_extra(st), own))
    return tuple(out)


# what a size comparison compares (graph/relations/sizes.py: tall = vertical extent, wide = larger horizontal
# extent, big = box volume, stated as the side of a cube of that volume so the trace orders objects as the
# answer does; a largest side would call a banana bigger than an apple)
_MEASURE_OF = {"height": "height", "width": "width", "volume": "volume"}


def size_measure(rel: str) -> str:
    """The length a Size key step states for a size relation (its mirror's: short -> height)."""
    r = _RELATIONS[rel]
    base = r.mirror_of or r.id
    attr = DERIVED.get(base, ("volume",))[0]
    return _MEASURE_OF.get(attr, "volume")


def size_scalar(extent: list[float], measure: str, volume: float) -> float:
    """One length of an object: its height or larger horizontal extent (from the rounded (larger horizontal,
    smaller horizontal, height) size), or the side of a cube of its box volume, rounded as key steps are."""
    if measure == "height":
        return extent[2]
    if measure == "width":
        return extent[0]
    return round(float(volume) ** (1.0 / 3.0), 3)


def one(v: Any) -> int:
    if isinstance(v, frozenset):
        if len(v) != 1:
            raise Reject("not_unique")
        return int(next(iter(v)))
    return int(v)


class KeyWriter:
    """Collects key steps, one of each type per phrase (the first time the reasoning looks at an object)."""

    letters = LETTERS

    def __init__(self, idx: SceneIndex, steps: list[Step]) -> None:
        self.idx, self.steps = idx, steps
        self.out: list[KeyStep] = []
        self._done: dict[str, set[str]] = {"Position": set(), "Size": set(), "Orientation": set()}
        self.final_orient = False  # the answer object's orientation decides a relation: perceive it too
        self.one = one
        self.size_measure = size_measure  # for ops (they cannot import this module)

    def name(self, o: int) -> str:
        return self.idx.phrase.get(o) or f"the target {self.idx.category[o]}"

    def pos(self, o: int, phrase: str | None = None) -> None:
        ph = phrase or self.idx.phrase.get(o) or f"the target {self.idx.category[o]}"
        done = self._done["Position"]
        if ph not in done:
            done.add(ph)
            self.out.append(KeyStep("Position", ph, self.idx.key_point(o)))

    def size(self, o: int, measure: str = "volume") -> None:
        """RoboRefer's Size step: one length in metres, the one the reasoning compares (`measure`: "height",
        "width" or "volume", the side of a cube of the box's volume); the full 3-D size stays in `extent`."""
        ph = self.name(o)
        done = self._done["Size"]
        if ph not in done:
            done.add(ph)
            ext = round_key(self.idx.size(o))
            scalar = size_scalar(ext, measure, self.idx.objects[o].box.volume)
            self.out.append(KeyStep("Size", ph, [scalar], measure, ext))

    def orient(self, o: int) -> None:
        ph = self.name(o)
        done = self._done["Orientation"]
        if ph not in done:
            done.add(ph)
            self.out.append(KeyStep("Orientation", ph, round_key(self.idx.front_cam(o))))


def key_steps(t: Template, env: dict[str, Any], ans: Any, idx: SceneIndex) -> list[KeyStep]:
    """One perceptual step per object the reasoning looks at, in program order, then the answer."""
    keys = KeyWriter(idx, t.steps)
    for kp in t.program.keys:
        rel = kp.rel_literal if kp.rel_slot is None else env[kp.rel_slot]
        measure = size_measure(rel) if rel is not None and _RELATIONS[rel].key_step == "Size" else ""
        for nm in kp.single:
            o = one(env[nm])
            keys.pos(o)
            if measure:
                keys.size(o, measure)
        for nm in kp.lists:
            o = env[nm]
            keys.pos(o)
            if measure:
                keys.size(o, measure)
        if kp.own:
            kp.step.impl.key_steps(kp.step, kp.extra, env, rel, keys)
    if isinstance(ans, PointValue):
        phrase_of = idx.phrase
        if ans.region is not None:
            r = ans.region
            phrase = (
                f"the free space {r.kind.replace('_', ' ')} "
                + " and ".join(phrase_of.get(a, str(a)) for a in r.anchors if a in phrase_of)
                if r.kind in FREE_KINDS
                else f"the free space at the {r.label}"
            )
            keys.out.append(KeyStep("Position", phrase, round_key(ans.point)))
        else:
            if keys.final_orient:
                keys.orient(ans.object_id)  # type: ignore[arg-type]
            keys.pos(ans.object_id)  # type: ignore[arg-type]
    return keys.out


def check_key_phrases(key_steps: list[KeyStep], struct: dict[str, Any], targets: list[int], idx: SceneIndex) -> None:
    """Every key step must name its object so a reward function (and `verify`) can find it: a graph phrase, a
    drawn mark, the free space, or, for the final position only, the answer target. An object with no unique
    phrase looked at on the way (e.g. the bottle a `between` step described) cannot be named: Reject."""
    names = idx.phrase_set
    marks = {f"the object marked ({m['label']})" for m in struct.get("marks") or []}
    last = key_steps[-1] if key_steps else None
    for ks in key_steps:
        ph = ks.phrase
        if ph in names or ph in marks or (ks.type == "Position" and ph.startswith("the free space")):
            continue
        if ks is last and ks.type == "Position" and targets:
            continue
        raise Reject("unnamed_key_step")
