"""The typed steps a template program is made of: what each takes, returns and counts as.

Why declarative: the compiler type-checks programs against this table (so a bad template fails at load
with file:line), the step count of a template is known before any scene is seen (formats.md rule), and
the executor and the verifier agree on what an op means without sharing code.
"""

from __future__ import annotations

from dataclasses import dataclass, field

# Relations that order two objects (pairwise comparison, mirror pairs): usable in relate, compare,
# superlative, ordinal and choose.
ORDERED = ("left", "right", "front", "behind", "above_world", "below_world", "above_image", "below_image",
           "tall", "short", "big", "small", "wide", "thin")
# Binary relations that do not order (a property of the pair).
PAIRWISE = ("inside", "outside", "facing", "facing_away", "touching", "far_from", "next_to", "on")
BINARY = ORDERED + PAIRWISE
# "A closer to C than B": ternary, needs an anchor C.
ANCHORED = ("close", "far")
SIZE_RELATIONS = ("tall", "short", "big", "small", "wide", "thin")
ORIENTATION_RELATIONS = ("facing", "facing_away")
QUANTITIES = {  # quantity -> (number of objects, relation id recorded, unit kind)
    "distance": (2, "distance", "length"),
    "depth": (1, "depth", "length"),
    "height": (1, "tall", "length"),
    "width": (1, "wide", "length"),
    "angle": (2, "angle", "angle"),
    "rotation_horizontal": (1, "rotation_horizontal", "turn"),
    "rotation_vertical": (1, "rotation_vertical", "turn"),
}
FREE_KINDS = ("left_of", "right_of", "in_front_of", "behind", "between")
REGION_KINDS = ("corner", "edge")
TURN_AXES = {"horizontal": ("left", "right"), "vertical": ("up", "down")}

SLOT_TYPES = ("object", "anchor", "relation", "direction", "surface", "number", "category", "color", "region", "spot")

# Value types flowing between steps.
SET, OBJECT, POINT, BOOL, OPTION, NUMBER, MARKS = "set", "object", "point", "bool", "option", "number", "marks"
ANSWER_TYPES = (OBJECT, POINT, BOOL, OPTION, NUMBER)


@dataclass(frozen=True)
class Arg:
    kind: str  # set | object | objects | relation | direction | surface | region | number | category | color |
    #           bools | quantity | options | style | axis | mode | int
    required: bool = False


@dataclass(frozen=True)
class OpSpec:
    name: str
    args: dict[str, Arg]
    out: str
    relations: tuple[str, ...] = ()  # allowed relation ids for a `relation` argument
    doc: str = ""
    extra: dict = field(default_factory=dict)


OPS: dict[str, OpSpec] = {o.name: o for o in [
    OpSpec("filter", {"in": Arg("set"), "category": Arg("category"), "color": Arg("color"), "on": Arg("surface")},
           SET, doc="keep objects of a category / colour / standing on a surface (intrinsic: 0 steps)"),
    OpSpec("relate", {"in": Arg("set"), "relation": Arg("relation", True), "anchor": Arg("object", True)}, SET,
           BINARY, doc="keep objects x with relation(x, anchor) (anchor + phrase: 2 steps)"),
    OpSpec("between", {"in": Arg("set"), "anchors": Arg("objects", True)}, SET,
           doc="keep objects between two anchors (2 anchors + phrase: 3 steps)"),
    OpSpec("superlative", {"in": Arg("set"), "relation": Arg("relation", True), "anchor": Arg("object")}, OBJECT,
           ORDERED + ANCHORED, doc="the one object that wins the relation against all others (0 steps, 2 with anchor)"),
    OpSpec("ordinal", {"in": Arg("set"), "relation": Arg("relation", True), "rank": Arg("number", True)}, OBJECT,
           ORDERED, doc="the rank-th object along the relation's order (image position: 0 steps)"),
    OpSpec("at", {"in": Arg("set"), "spot": Arg("spot", True)}, SET,
           doc="keep objects at a named corner or edge of a surface (surface + phrase: 2 steps)"),
    OpSpec("is_at", {"a": Arg("object", True), "spot": Arg("spot", True)}, BOOL,
           doc="is the object at a named corner or edge of a surface (2 steps)"),
    OpSpec("locate", {"of": Arg("object")}, POINT, doc="the answer point of one object (0 steps)"),
    OpSpec("free_space", {"direction": Arg("direction"), "anchor": Arg("object"), "anchors": Arg("objects"),
                          "region": Arg("region")}, POINT,
           doc="a free point: direction of an anchor (2 steps), between two anchors (3), a corner/edge region (1)"),
    OpSpec("compare", {"relation": Arg("relation", True), "a": Arg("object", True), "b": Arg("object", True),
                       "anchor": Arg("object")}, BOOL, BINARY + ANCHORED,
           doc="does relation(a, b[, anchor]) hold (2 steps, 3 with anchor)"),
    OpSpec("all", {"of": Arg("bools", True)}, BOOL, doc="logical and of earlier yes/no steps (0 steps)"),
    OpSpec("measure", {"quantity": Arg("quantity", True), "of": Arg("object"), "to": Arg("object")}, NUMBER,
           doc="a metric quantity (steps: objects involved - 1)"),
    OpSpec("mark", {"in": Arg("set"), "count": Arg("int"), "style": Arg("style")}, MARKS,
           doc="draw labelled boxes or points on a copy of the image around `count` objects (0 steps)"),
    OpSpec("choose", {"options": Arg("options", True), "relation": Arg("relation", True), "anchor": Arg("object"),
                      "mode": Arg("mode")}, OPTION, BINARY + ANCHORED,
           doc="pick the option that wins (mode most) or the only one that satisfies (mode which); 1 step + 2 with anchor"),
    OpSpec("camera_turn", {"axis": Arg("axis", True)}, OPTION,
           doc="multi-view: which way the camera turned from the first image to the second (1 step)"),
]}


def step_weight(op: str, args: dict) -> int:
    """Contribution of one step to the question's step count (formats.md: anchors + directional phrases)."""
    if op in ("relate", "at", "is_at"):
        return 2
    if op == "between":
        return 3
    if op == "superlative":
        return 2 if args.get("anchor") is not None else 0
    if op == "free_space":
        if args.get("anchors") is not None:
            return 3
        if args.get("region") is not None:
            return 1
        return 2
    if op == "compare":
        return 3 if args.get("anchor") is not None else 2
    if op == "measure":
        return 1 if args.get("to") is not None else 0
    if op == "choose":
        return 3 if args.get("anchor") is not None else 1
    if op == "camera_turn":
        return 1
    return 0


def count_steps(steps: list[tuple[str, dict]]) -> int:
    """The question's step count: at least 1 (a plain reference is one step)."""
    return max(1, sum(step_weight(op, a) for op, a in steps))


# Ops whose removal must change the answer (the degeneracy check drops each in turn).
DROPPABLE = ("relate", "between", "at", "superlative", "ordinal", "compare", "is_at")
