"""Mark wording (recipes/templates/*.yaml): a drawn mark is called a mark, label or point, never by a word
that is also an object category ("Which box is on the object ...": audit round 3, sim/0/sim:000021/v0:07, read
as a physical box while 'box' and 'storage box' are categories)."""

from __future__ import annotations

import re
from pathlib import Path

import yaml

ROOT = Path(__file__).resolve().parents[1]
MARK_WORDS = {"mark", "marks", "marked", "label", "labels", "labelled", "point", "points"}


def _category_words() -> set[str]:
    raw = yaml.safe_load((ROOT / "refspatial_gen/truth/data/category_sizes.yaml").read_text())
    names = list(raw["categories"]) + list(raw.get("aliases") or {})
    return {w for n in names for w in str(n).lower().replace("_", " ").split()}


def _mark_template_words() -> set[str]:
    """Every literal word of the text lines of templates that draw marks (slot names stripped)."""
    words: set[str] = set()
    for p in sorted((ROOT / "recipes/templates").glob("*.yaml")):
        for t in (yaml.safe_load(p.read_text()) or {}).get("templates") or []:
            if any(step.get("op") == "mark" for step in t.get("program") or []):
                for line in t.get("text") or []:
                    literal = re.sub(r"\{[a-z_.]+\}", " ", line)  # {rel.sup}, {anchor}, {choices}
                    words |= set(re.findall(r"[a-z]+", literal.lower()))
    return words


def test_mark_words_are_no_category():
    assert not MARK_WORDS & _category_words()


def test_templates_that_draw_marks_never_call_one_a_box():
    words = _mark_template_words()
    assert words & MARK_WORDS  # the templates are read: they do speak of marks
    clash = (words - MARK_WORDS - {"object", "objects", "one", "ones"}) & {"box", "boxes", "rectangle", "frame"}
    assert not clash, f"templates drawing marks call one {sorted(clash)}: a physical object's word"
