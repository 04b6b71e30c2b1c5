"""Wording of a question: slot values rendered through the template text grammar (qa/text.py) and the
default wording of relations, directions, surfaces and spots (qa/lexicon.py)."""

from __future__ import annotations

from typing import Any

from refspatial_gen.graph.phrases import display_category
from refspatial_gen.qa import lexicon
from refspatial_gen.qa.index import Reject, SceneIndex
from refspatial_gen.qa.program import Template
from refspatial_gen.qa.sample_rng import SampleRng
from refspatial_gen.qa.text import Seq, parse, render
from refspatial_gen.qa.values import Context

_PARSED: dict[str, Seq] = {}


def parsed(text: str) -> Seq:
    """The parsed form of a lexicon text (parsed once per process)."""
    s = _PARSED.get(text)
    if s is None:
        s = _PARSED[text] = parse(text)
    return s


def surface_name(ctx: Context, sid: str) -> str:
    s = ctx.idx.surfaces.get(sid)
    if s is None:
        return f"the {sid}"
    return s.name or f"the {s.kind}"


def spot_phrase(idx: SceneIndex, spot: tuple[str, str, str], form: str = "") -> str:
    """("corner", "table", "far-left") -> "the far-left corner of the table"; edges carry their own noun."""
    kind, sid, label = spot
    s = idx.surfaces.get(sid)
    sname = (s.name or f"the {s.kind}") if s is not None else f"the {sid}"
    if form == "surface":
        return sname
    lab = label if label.endswith(kind) else f"{label} {kind}"
    if form == "label":
        return lab
    return f"the {lab} of {sname}"


def _plural(word: str) -> str:
    if word.endswith(("s", "x", "ch", "sh")):
        return word + "es"
    if word.endswith("y") and word[-2:-1] not in "aeiou":
        return word[:-1] + "ies"
    return word + "s"


class Renderer:
    """Placeholder values of one instance (`{a}`, `{rel.sup}`, `{choices}`...) for text.render."""

    def __init__(
        self, t: Template, env: dict[str, Any], ctx: Context, rng: SampleRng, choices: str, instruction: str
    ) -> None:
        self.t, self.env, self.ctx, self.rng = t, env, ctx, rng
        self.choices, self.instruction = choices, instruction

    def __call__(self, name: str) -> str:
        base, _, form = name.partition(".")
        if base == "choices":
            return self.choices
        if base == "instruction":
            return self.instruction
        s = self.t.slots[base]
        v = self.env[base]
        idx = self.ctx.idx
        if s.type in ("object", "anchor"):
            if form == "category":
                return display_category(idx.category[v])
            if form == "color":
                return idx.color.get(v) or ""
            return idx.phrase[v]
        if s.type == "relation":
            f = form or "prep"
            mod = f == "mod"
            if mod:
                f = "prep"
            seq = s.phrases.get(v, {}).get(f)
            if seq is None:
                text = lexicon.RELATION_FORMS.get(v, {}).get(f)
                if text is None:
                    raise Reject("no_wording")
                seq = parsed(text)
            out = render(seq, self, self.rng, sentence=False)
            return self._relative(v, out) if mod else out
        if s.type == "direction":
            seq = s.phrases.get(v, {}).get("") or parsed(lexicon.DIRECTION_FORMS.get(v, v.replace("_", " ")))
            return render(seq, self, self.rng, sentence=False)
        if s.type == "number":
            return str(v) if form == "value" else lexicon.ORDINALS.get(v, f"{v}th")
        if s.type == "category":
            word = self._category_word(v)
            return _plural(word) if form == "plural" else word
        if s.type == "color":
            return v
        if s.type == "surface":
            return surface_name(self.ctx, v)
        if s.type == "region":
            return surface_name(self.ctx, v.surface_id) if form == "surface" else v.label
        if s.type == "spot":
            return spot_phrase(self.ctx.idx, v, form)
        return str(v)

    def _relative(self, rel: str, prep: str) -> str:
        """A relation after a noun (`{rel.mod}`): "that is" / "which is" before an adjectival wording
        ("the spoon that is larger than the bowl"), optional before a preposition ("the cup [that is] left
        of the bowl"). Without it an adjective chain reads as the question's predicate ("Is the spoon larger
        than the orange spoon shorter than the bowl?")."""
        adjectival = rel in lexicon.ADJECTIVAL or prep.endswith(" than")
        if adjectival or self.rng.random() < 0.5:
            return f"{lexicon.RELATIVE[int(self.rng.integers(len(lexicon.RELATIVE)))]} {prep}"
        return prep

    def _category_word(self, category: str) -> str:
        """The category's name or, half of the time, a curated synonym (qa/data/synonyms.yaml) that is not
        itself the category of an object in the frame."""
        syn = lexicon.category_synonyms(category)
        if not syn or self.rng.random() < 0.5:
            return display_category(category)
        cats = set(self.ctx.idx.category.values())
        ok = [w for w in syn if w not in cats]
        return ok[int(self.rng.integers(len(ok)))] if ok else display_category(category)
