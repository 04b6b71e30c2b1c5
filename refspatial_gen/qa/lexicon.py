"""Default wording for relations, directions, ordinals and output instructions.

Why in one table: a relation id (relations.md) must read the same way in every template, and the
compiler needs to know which forms exist to reject `{rel.superlative}` on a relation that has none.
Templates can override any form per slot (`phrases:` in the slot) without touching this file.
Text uses the template grammar ({a|b} synonyms, [optional]).
"""

from __future__ import annotations

from pathlib import Path
from typing import Any

import yaml

# relation id -> form -> text. Forms: prep ("A is <prep> B"), cmp ("which is <cmp>"), sup ("the <sup> X"),
# ord ("the second X <ord>"), noun (a name for measured quantities).
# above/below always say which: "in the image" or "in the real world" ("physically"); unqualified, a person
# reads "is the glass above the camera?" either way (audit, issue 15).
RELATION_FORMS: dict[str, dict[str, str]] = {
    "left": {
        "prep": "{to the left of|left of|on the left side of}",
        "cmp": "further to the left",
        "sup": "leftmost",
        "ord": "from the left",
        "adj": "on the left",
    },
    "right": {
        "prep": "{to the right of|right of|on the right side of}",
        "cmp": "further to the right",
        "sup": "rightmost",
        "ord": "from the right",
        "adj": "on the right",
    },
    "front": {
        "prep": "{in front of|closer to the camera than}",
        "cmp": "closer to the {camera|viewer}",
        "sup": "{closest to the camera|nearest to the viewer|frontmost}",
        "ord": "from the front",
        "adj": "in front",
    },
    "behind": {
        "prep": "{behind|farther from the camera than}",
        "cmp": "farther from the {camera|viewer}",
        "sup": "{farthest from the camera|farthest from the viewer|rearmost}",
        "ord": "from the back",
        "adj": "at the back",
    },
    "above_world": {
        # "higher", not "above": "physically above the tray" reads as over it, and beside it a clearly higher
        # object is above it too (graph/relations/vertical_clear.py; pre-audit round 5)
        "prep": "{physically higher than|higher up, in the real world, than|physically higher up than}",
        "cmp": "higher up in the real world",
        "sup": "physically highest",
        "adj": "higher up",
    },
    "below_world": {
        "prep": "{physically lower than|lower down, in the real world, than|physically lower down than}",
        "cmp": "lower down in the real world",
        "sup": "physically lowest",
        "adj": "lower down",
    },
    "above_image": {
        "prep": "{higher in the image than|above, in the image,|above, from the image's perspective,}",
        "cmp": "higher in the image",
        "sup": "topmost [in the image]",
        "ord": "from the top of the image",
        "adj": "higher in the image",
    },
    "below_image": {
        "prep": "{lower in the image than|below, in the image,|below, from the image's perspective,}",
        "cmp": "lower in the image",
        "sup": "bottommost [in the image]",
        "ord": "from the bottom of the image",
        "adj": "lower in the image",
    },
    "tall": {"prep": "taller than", "cmp": "taller", "sup": "tallest", "adj": "tall"},
    "short": {"prep": "shorter than", "cmp": "shorter", "sup": "shortest", "adj": "short"},
    "big": {"prep": "{bigger|larger} than", "cmp": "{bigger|larger}", "sup": "{biggest|largest}", "adj": "big"},
    "small": {"prep": "smaller than", "cmp": "smaller", "sup": "smallest", "adj": "small"},
    "wide": {"prep": "wider than", "cmp": "wider", "sup": "widest", "adj": "wide"},
    "thin": {
        "prep": "{thinner|narrower} than",
        "cmp": "{thinner|narrower}",
        "sup": "{thinnest|narrowest}",
        "adj": "thin",
    },
    "close": {"prep": "closer to", "cmp": "closer to", "sup": "{closest|nearest} to"},
    "far": {"prep": "farther from", "cmp": "farther from", "sup": "farthest from"},
    "inside": {"prep": "{inside|in}"},
    "outside": {"prep": "outside"},
    "facing": {"prep": "facing"},
    "facing_away": {"prep": "facing away from"},
    "touching": {"prep": "{touching|in contact with}"},
    "far_from": {"prep": "far from"},
    "next_to": {"prep": "{next to|beside}"},
    "on": {"prep": "on"},
    "between": {"prep": "between"},
    "distance": {"noun": "distance"},
    "depth": {"noun": "distance from the camera"},
    "angle": {"noun": "angle"},
    "rotation_horizontal": {"noun": "horizontal rotation"},
    "rotation_vertical": {"noun": "vertical rotation"},
}

# free-space / region kinds -> phrase ("a free spot <phrase> the cup")
DIRECTION_FORMS: dict[str, str] = {
    "left_of": "{to the left of|left of}",
    "right_of": "{to the right of|right of}",
    "in_front_of": "in front of",
    "behind": "behind",
    "between": "between",
    "left": "left",
    "right": "right",
    "up": "up",
    "down": "down",
}

ORDINALS = {1: "first", 2: "second", 3: "third", 4: "fourth", 5: "fifth", 6: "sixth", 7: "seventh", 8: "eighth"}

POINT_INSTRUCTIONS = (
    "Your answer should be formatted as a list of tuples, i.e. \\[(x1, y1)\\], where each tuple contains the x and y "
    "coordinates of a point satisfying the conditions above. The coordinates should be between 0 and 1, "
    "indicating the normalized pixel locations of the points in the image.",
    "Answer with a list of tuples \\[(x1, y1), ...\\] of normalized image coordinates between 0 and 1.",
    "Please output the point as a list of tuples \\[(x, y)\\] with x and y normalized to \\[0, 1\\] by the image width "
    "and height.",
)

CHOICE_INSTRUCTIONS = ("Answer with the option's letter.", "Choose one option.", "")


# "that is" before a relation used after a noun ("the cup {rel.mod} the bowl"): always for relations worded as
# adjectives ("the spoon that is larger than the bowl", never "the spoon larger than the bowl shorter than..."),
# optional for prepositions ("the cup [that is] to the left of the bowl")
ADJECTIVAL = frozenset({"tall", "short", "big", "small", "wide", "thin", "close", "far", "far_from"})
RELATIVE = ("that is", "which is")

SYNONYMS_FILE = Path(__file__).with_name("data") / "synonyms.yaml"


def _load_synonyms(path: Path = SYNONYMS_FILE) -> tuple[dict[str, tuple[str, ...]], dict[str, dict[str, list[str]]]]:
    """(category -> synonyms, relation -> form -> extra phrasings) from the curated data file."""
    with open(path, encoding="utf-8") as f:
        data: dict[str, Any] = yaml.safe_load(f) or {}
    cats = {str(k): tuple(str(x) for x in v) for k, v in sorted((data.get("categories") or {}).items())}
    rels = {
        str(k): {str(f): [str(x) for x in xs] for f, xs in v.items()} for k, v in (data.get("relations") or {}).items()
    }
    return cats, rels


def _merge(text: str, extra: list[str]) -> str:
    """A form's text with extra alternatives: merged into a plain `{a|b}` group, else a new group around it."""
    if text.startswith("{") and text.endswith("}") and text.count("{") == 1 and "[" not in text:
        return "{" + "|".join([text[1:-1], *extra]) + "}"
    return "{" + "|".join([text, *extra]) + "}"


CATEGORY_SYNONYMS, _RELATION_SYNONYMS = _load_synonyms()
for _rel, _forms in sorted(_RELATION_SYNONYMS.items()):
    for _form, _extra in sorted(_forms.items()):
        if _rel not in RELATION_FORMS or _form not in RELATION_FORMS[_rel]:
            raise ValueError(f"{SYNONYMS_FILE}: relation {_rel!r} has no {_form!r} form to add synonyms to")
        RELATION_FORMS[_rel][_form] = _merge(RELATION_FORMS[_rel][_form], _extra)


def category_synonyms(category: str) -> tuple[str, ...]:
    """Other names of a category (empty when none is curated)."""
    return CATEGORY_SYNONYMS.get(category, ())
