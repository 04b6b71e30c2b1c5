"""Detection vocabularies: which names the open-vocabulary detector is prompted with.

Shipped lists (data/, sources and licences in data/SOURCES.md): `lvis` (LVIS v1, 1203 names),
`lvis-frequent` (its 405 frequent names: 'f', seen in more than 100 training images), `openimages`
(Open Images V7 boxable classes), `coco` (the 80 COCO thing classes). A recipe may instead give a list
of names or a `.txt` file with one name a line. Dataset names are turned into words a question can use:
"bus_(vehicle)" -> "bus", "dining_table" -> "dining table"; where stripping a qualifier would make two
names collide ("mouse_(animal_rodent)", "mouse_(computer_equipment)"), the qualifier is kept in words
("mouse (computer equipment)").
"""

from __future__ import annotations

import csv
import re
from dataclasses import dataclass
from functools import lru_cache
from pathlib import Path

DATA = Path(__file__).with_name("data")
SHIPPED = ("coco", "lvis", "lvis-frequent", "openimages")
COCO_THINGS = (
    "person",
    "bicycle",
    "car",
    "motorcycle",
    "airplane",
    "bus",
    "train",
    "truck",
    "boat",
    "traffic light",
    "fire hydrant",
    "stop sign",
    "parking meter",
    "bench",
    "bird",
    "cat",
    "dog",
    "horse",
    "sheep",
    "cow",
    "elephant",
    "bear",
    "zebra",
    "giraffe",
    "backpack",
    "umbrella",
    "handbag",
    "tie",
    "suitcase",
    "frisbee",
    "skis",
    "snowboard",
    "sports ball",
    "kite",
    "baseball bat",
    "baseball glove",
    "skateboard",
    "surfboard",
    "tennis racket",
    "bottle",
    "wine glass",
    "cup",
    "fork",
    "knife",
    "spoon",
    "bowl",
    "banana",
    "apple",
    "sandwich",
    "orange",
    "broccoli",
    "carrot",
    "hot dog",
    "pizza",
    "donut",
    "cake",
    "chair",
    "couch",
    "potted plant",
    "bed",
    "dining table",
    "toilet",
    "tv",
    "laptop",
    "mouse",
    "remote",
    "keyboard",
    "cell phone",
    "microwave",
    "oven",
    "toaster",
    "sink",
    "refrigerator",
    "book",
    "clock",
    "vase",
    "scissors",
    "teddy bear",
    "hair drier",
    "toothbrush",
)


@dataclass(frozen=True)
class Category:
    name: str  # the words used in prompts and in questions ("dining table")
    source: str  # the name as the list gives it ("dining_table")


def _words(raw: str, keep_qualifier: bool) -> str:
    raw = (
        raw.strip().split(" ")[-1] if "_(" in raw and " " in raw.strip() else raw
    )  # LVIS "monitor_(...) computer_monitor"
    m = re.fullmatch(r"(.*?)_\((.*)\)", raw.strip())
    base, qual = (m.group(1), m.group(2)) if m else (raw.strip(), None)
    words = base.replace("_", " ").strip()
    if keep_qualifier and qual:
        words = f"{words} ({qual.replace('_', ' ')})"
    return re.sub(r"\s+", " ", words).lower()


def _from_raw(raw: list[str]) -> list[Category]:
    plain = [_words(r, False) for r in raw]
    counts: dict[str, int] = {}
    for w in plain:
        counts[w] = counts.get(w, 0) + 1
    out, seen = [], set()
    for r, w in zip(raw, plain):
        name = _words(r, True) if counts[w] > 1 else w
        if name and name not in seen:
            seen.add(name)
            out.append(Category(name, r))
    return out


def _read_tsv(name: str) -> list[dict[str, str]]:
    with open(DATA / name, encoding="utf-8") as f:
        rows = [ln for ln in f if not ln.startswith("#")]
    return list(csv.DictReader(rows, delimiter="\t"))


@lru_cache(maxsize=8)
def _shipped(which: str) -> tuple[Category, ...]:
    if which == "coco":
        return tuple(Category(n, n) for n in COCO_THINGS)
    if which in ("lvis", "lvis-frequent"):
        rows = _read_tsv("lvis_v1_categories.tsv")
        if which == "lvis-frequent":
            rows = [r for r in rows if r["frequency"] == "f"]
        return tuple(_from_raw([r["name"] for r in rows]))
    if which == "openimages":
        return tuple(_from_raw([r["name"] for r in _read_tsv("openimages_v7_boxable.tsv")]))
    raise KeyError(which)


def vocabulary_problem(spec: str | list) -> str | None:
    """Why a vocabulary spec cannot be used, or None."""
    if isinstance(spec, list):
        if not spec or not all(isinstance(x, str) and x.strip() for x in spec):
            return "a list of non-empty names"
        return None
    if spec in SHIPPED:
        return None
    if spec.endswith(".txt"):
        return None if Path(spec).expanduser().is_file() else f"vocabulary file {spec!r} does not exist"
    return f"one of {', '.join(SHIPPED)}, a list of names, or a .txt file; got {spec!r}"


def load_vocabulary(spec: str | list, exclude: list[str] | None = None) -> list[Category]:
    """The categories of a vocabulary spec, in list order, without `exclude` (matched on the words)."""
    if isinstance(spec, list):
        cats = _from_raw([str(x) for x in spec])
    elif spec in SHIPPED:
        cats = list(_shipped(spec))
    else:
        lines = Path(spec).expanduser().read_text(encoding="utf-8").splitlines()
        cats = _from_raw([ln for ln in (x.strip() for x in lines) if ln and not ln.startswith("#")])
    drop = {_words(x, True) for x in exclude or []} | {_words(x, False) for x in exclude or []}
    return [c for c in cats if c.name not in drop]
