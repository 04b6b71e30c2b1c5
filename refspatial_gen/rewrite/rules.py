"""Word lists the rewrite checks compare: spatial concepts, answer words, object nouns, viewpoint phrases.

Why word groups and not a paraphrase model: a rewrite is kept only if it provably says the same thing. A
question's meaning here is carried by its object phrases (checked verbatim), its numbers, and a small set
of spatial words; a rewrite may reword everything else but must name the same spatial concepts (as a
set: "farther" may become "more distant", never "closer"), the same negation and the same perspective.
The lists err on the strict side: a good paraphrase that uses an unlisted synonym is only lost, a wrong
one that flips a relation is caught.
"""

from __future__ import annotations

import re
from collections import Counter

# concept -> words that express it (lower case, whole words; a hyphenated word also counts by its parts)
CONCEPTS: dict[str, tuple[str, ...]] = {
    "left": ("left", "leftmost", "left-hand", "leftward"),
    "right": ("right", "rightmost", "right-hand", "rightward"),
    "front": ("front", "fronts", "frontmost", "foreground", "ahead"),
    "behind": ("behind", "back", "backs", "rear", "rearmost", "background", "beyond"),
    "above": ("above", "higher", "highest", "over", "top", "topmost", "upper", "up", "upward", "upwards"),
    "below": (
        "below",
        "lower",
        "lowest",
        "under",
        "underneath",
        "beneath",
        "bottom",
        "bottommost",
        "down",
        "downward",
        "downwards",
    ),
    "tall": ("tall", "taller", "tallest", "height"),
    "short": ("short", "shorter", "shortest"),
    "big": ("big", "bigger", "biggest", "large", "larger", "largest"),
    "small": ("small", "smaller", "smallest", "little", "tiny"),
    "wide": ("wide", "wider", "widest", "width", "broad", "broader", "broadest"),
    "thin": ("thin", "thinner", "thinnest", "narrow", "narrower", "narrowest", "slim", "slimmer", "slimmest"),
    "close": ("close", "closer", "closest", "near", "nearer", "nearest", "nearby"),
    "far": (
        "far",
        "farther",
        "farthest",
        "further",
        "furthest",
        "distant",
        "distance",
        "away",
        "apart",
        "depth",
        "deep",
    ),
    "inside": ("inside", "within", "into"),
    "outside": ("outside",),
    "between": ("between", "among", "middle", "amid"),
    "corner": ("corner", "corners"),
    "edge": ("edge", "edges", "border"),
    "facing": ("facing", "faces"),
    "touching": ("touching", "touch", "touches", "contact"),
    "beside": ("beside", "next", "adjacent", "alongside"),
    "angle": ("angle", "angles", "degree", "degrees"),
    "turn": ("turn", "turned", "rotate", "rotated", "rotation", "tilt", "tilted"),
    "horizontal": ("horizontal", "horizontally", "sideways"),
    "vertical": ("vertical", "vertically"),
    "negation": ("not", "no", "never", "nor", "neither", "isn't", "aren't", "doesn't", "don't", "without"),
    "first": ("first", "1st"),
    "second": ("second", "2nd"),
    "third": ("third", "3rd"),
    "fourth": ("fourth", "4th"),
    "fifth": ("fifth", "5th"),
    "sixth": ("sixth", "6th"),
    "marked": ("marked", "mark", "marks", "labelled", "labeled", "label"),
    "free": ("free", "empty", "vacant", "unoccupied", "clear", "open", "space", "spot", "area"),
}

# words whose appearance in a rewritten question (when the original did not have them) state an answer
ANSWER_WORDS = ("yes", "no", "true", "false", "correct", "incorrect", "indeed", "answer")

# perspective phrases (relations above/below are asked in the image or in the world): kept or absent alike
PERSPECTIVES = ("image's perspective", "real-world perspective", "in the image", "in the real world")

# an object-centred frame ("its left") changes the meaning of left/right/front/behind: never introduced
OBJECT_FRAME = (
    "its left",
    "its right",
    "its front",
    "its back",
    "their left",
    "their right",
    "own left",
    "own right",
    "object's perspective",
    "object's point of view",
    "your left",
    "your right",
)

# nouns a rewrite could name that are not in the scene (beside the scene's own categories and surfaces)
NOUNS = (
    "apple",
    "ball",
    "banana",
    "basket",
    "bed",
    "bench",
    "book",
    "bottle",
    "bowl",
    "box",
    "bread",
    "broccoli",
    "bucket",
    "cabinet",
    "candle",
    "car",
    "carrot",
    "chair",
    "clock",
    "computer",
    "couch",
    "counter",
    "cup",
    "cushion",
    "desk",
    "dish",
    "door",
    "drawer",
    "fork",
    "glass",
    "hat",
    "jar",
    "jug",
    "keyboard",
    "kettle",
    "knife",
    "lamp",
    "laptop",
    "lemon",
    "monitor",
    "mouse",
    "mug",
    "orange",
    "pan",
    "pen",
    "pencil",
    "person",
    "phone",
    "pillow",
    "plant",
    "plate",
    "pot",
    "remote",
    "scissors",
    "shelf",
    "shoe",
    "sink",
    "sofa",
    "speaker",
    "spoon",
    "sponge",
    "stool",
    "table",
    "teapot",
    "toy",
    "tray",
    "vase",
    "wall",
    "window",
    "floor",
    "ground",
    "cloth",
    "towel",
    "bag",
    "backpack",
    "tv",
    "television",
    "block",
    "cube",
    "cylinder",
    "sphere",
    "tin",
    "carton",
    "container",
    "dog",
    "cat",
    "man",
    "woman",
    "robot",
)
COLORS = (
    "red",
    "green",
    "blue",
    "yellow",
    "orange",
    "purple",
    "pink",
    "brown",
    "black",
    "white",
    "gray",
    "grey",
    "beige",
    "cyan",
    "magenta",
    "violet",
    "golden",
    "silver",
    "tan",
    "teal",
)

# the kind of question an answer needs: a rewrite must still ask for it (a point question may not become a
# yes/no question). "yesno": the first word is an auxiliary verb, or the body asks whether/if something is true.
FORM_CUES: dict[str, tuple[str, ...]] = {
    "point": (
        "where",
        "point",
        "locate",
        "find",
        "show",
        "mark",
        "indicate",
        "pick",
        "which",
        "identify",
        "what",
        "select",
        "choose",
    ),
    "choice": ("which", "what", "pick", "choose", "select", "who", "or", "direction", "way"),
    "number": ("how", "what", "estimate", "measure", "give", "tell", "which", "by"),
}
YESNO_FIRST = ("is", "are", "does", "do", "did", "can", "could", "would", "will", "was", "were", "has", "have")
YESNO_CUES = ("whether", "if", "true")

_WORD = re.compile(r"[a-z0-9]+(?:['\-][a-z0-9]+)*")
_NUMBER = re.compile(r"\d+(?:\.\d+)?")


def words(text: str) -> list[str]:
    """Lower-case words; a hyphenated word also yields its parts ("far-left" -> far-left, far, left)."""
    out: list[str] = []
    for w in _WORD.findall(text.lower()):
        out.append(w)
        if "-" in w:
            out.extend(w.split("-"))
    return out


def concepts(text: str) -> frozenset[str]:
    """The spatial concepts a text names (see CONCEPTS)."""
    ws = set(words(text))
    return frozenset(c for c, forms in CONCEPTS.items() if ws.intersection(forms))


def numbers(text: str) -> Counter:
    return Counter(_NUMBER.findall(text))


def asks_for(text: str, form: str) -> bool:
    """Does the text still ask the kind of question `form` (point, yesno, choice, number) needs?"""
    ws = words(text)
    if form == "yesno":  # a clause opens with an auxiliary verb ("Looking at it, is ..."), or whether/if/true
        firsts = {(words(c) or [""])[0] for c in re.split(r"[,.;:!?]", text)}
        return bool(firsts.intersection(YESNO_FIRST) or set(ws).intersection(YESNO_CUES))
    return bool(set(ws).intersection(FORM_CUES.get(form, ())))


def nouns_in(text: str, vocab: frozenset[str]) -> frozenset[str]:
    """Which vocabulary nouns (single or multi-word, plural -s/-es allowed) a text names."""
    t = " ".join(words(text))
    out = set()
    for v in vocab:
        if re.search(r"(?<![a-z0-9])" + re.escape(v) + r"(?:s|es)?(?![a-z0-9])", t):
            out.add(v)
    return frozenset(out)


def phrase_order(text: str, phrases: tuple[str, ...]) -> list[str]:
    """The phrases in the order they occur (longest first claims its span, as in mask_phrases)."""
    found: list[tuple[int, str]] = []
    for p in sorted(set(phrases), key=lambda s: (-len(s), s)):
        pat = re.compile(r"(?<![A-Za-z0-9])" + re.escape(p) + r"(?![A-Za-z0-9])", re.IGNORECASE)
        for m in pat.finditer(text):
            found.append((m.start(), p))
        text = pat.sub(lambda m: "\u2063" * len(m.group(0)), text)
    return [p for _, p in sorted(found)]


def mask_phrases(text: str, phrases: tuple[str, ...]) -> tuple[str, Counter]:
    """Replace each phrase (longest first, case-insensitive, whole words) by a marker; count replacements."""
    counts: Counter = Counter()
    for p in sorted(set(phrases), key=lambda s: (-len(s), s)):
        pat = re.compile(r"(?<![A-Za-z0-9])" + re.escape(p) + r"(?![A-Za-z0-9])", re.IGNORECASE)
        text, n = pat.subn(" \u2063 ", text)
        counts[p] += n
    return text, counts
