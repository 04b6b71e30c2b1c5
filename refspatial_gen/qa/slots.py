"""Template compilation, part one: the compile context (errors as file:line) and the typed slot
declarations (`slots:` of a template; docs/templates.md lists the types and their keys)."""

from __future__ import annotations

from typing import Any

from refspatial_gen.core.errors import RecipeError
from refspatial_gen.qa.ops.base import FREE_KINDS, REGION_KINDS, SLOT_TYPES, TURN_AXES
from refspatial_gen.qa.program import SlotSpec
from refspatial_gen.qa.text import Seq, TextSyntaxError, parse
from refspatial_gen.yamlpos import line_of

SLOT_KEYS = ("type", "choices", "category", "has_front", "min", "max", "kinds", "phrases", "description")
SLOT_FORMS = {  # placeholder suffixes each slot type renders
    "object": ("", "category", "color"),
    "anchor": ("", "category", "color"),
    "relation": ("", "prep", "mod", "cmp", "sup", "ord", "adj", "noun"),  # mod: prep after a noun
    "direction": ("",),
    "surface": ("",),
    "number": ("", "value"),
    "category": ("", "plural"),
    "color": ("",),
    "region": ("", "surface"),
    "spot": ("", "surface", "label"),
}
BUILTIN_PLACEHOLDERS = ("choices", "instruction")
Path = tuple[Any, ...]  # a YAML path (keys and indices) naming where a problem is


class Ctx:
    """Where compile problems go: each becomes a RecipeError with the file and the line of its YAML path."""

    def __init__(self, file: str, lines: dict[tuple[Any, ...], int], errors: list[RecipeError]) -> None:
        self.file, self.lines, self.errors = file, lines, errors

    def err(self, path: Path, msg: str) -> None:
        self.errors.append(RecipeError(self.file, line_of(self.lines, path), msg))


def compile_slots(v: Any, path: Path, ctx: Ctx, known_rel: tuple[str, ...]) -> dict[str, SlotSpec]:
    if v is None:
        return {}
    if not isinstance(v, dict):
        ctx.err(path, f"slots must be a mapping of name -> type, got {type(v).__name__}")
        return {}
    out: dict[str, SlotSpec] = {}
    for name, spec in v.items():
        s = _compile_slot(name, spec, path + (name,), ctx, known_rel)
        if s is not None:
            out[name] = s
    return out


def _compile_slot(name: Any, spec: Any, p: Path, ctx: Ctx, known_rel: tuple[str, ...]) -> SlotSpec | None:
    if not isinstance(name, str) or not name.isidentifier():
        ctx.err(p, f"slot name {name!r} must be an identifier")
        return None
    if name in BUILTIN_PLACEHOLDERS or name in known_rel or name == "all":
        ctx.err(p, f"slot name {name!r} is reserved")
        return None
    if isinstance(spec, str):
        spec = {"type": spec}
    if not isinstance(spec, dict):
        ctx.err(p, f"slot {name!r} must be a type name or a mapping, got {type(spec).__name__}")
        return None
    for k in spec:
        if k not in SLOT_KEYS:
            ctx.err(p + (k,), f"unknown key {k!r} in slot {name!r} (known: {', '.join(SLOT_KEYS)})")
    ty = spec.get("type")
    if ty not in SLOT_TYPES:
        ctx.err(p + ("type",), f"slot {name!r}: unknown slot type {ty!r} (known: {', '.join(SLOT_TYPES)})")
        return None
    s = SlotSpec(name, ty, line_of(ctx.lines, p))
    ch = spec.get("choices")
    if ch is not None:
        _slot_choices(s, ch, p, ctx, known_rel)
    _slot_limits(s, spec, p, ctx)
    phr = spec.get("phrases")
    if phr is not None:
        _slot_phrases(s, phr, p, ctx)
    return s


def _slot_choices(s: SlotSpec, ch: Any, p: Path, ctx: Ctx, known_rel: tuple[str, ...]) -> None:
    name, ty = s.name, s.type
    if not isinstance(ch, list) or not ch or not all(isinstance(c, (str, int)) and not isinstance(c, bool) for c in ch):
        ctx.err(p + ("choices",), f"slot {name!r}: choices must be a non-empty list of names")
        return
    s.choices = tuple(ch)
    if ty == "relation":
        for j, c in enumerate(ch):
            if c not in known_rel:
                ctx.err(p + ("choices", j), f"unknown relation {c!r} (known: {', '.join(known_rel)})")
    elif ty == "direction":
        allowed = FREE_KINDS + tuple(x for pair in TURN_AXES.values() for x in pair)
        for j, c in enumerate(ch):
            if c not in allowed:
                ctx.err(p + ("choices", j), f"unknown direction {c!r} (known: {', '.join(allowed)})")
    elif ty == "number":
        if not all(isinstance(c, int) and c >= 1 for c in ch):
            ctx.err(p + ("choices",), f"slot {name!r}: number choices must be integers >= 1")


def _slot_limits(s: SlotSpec, spec: dict[str, Any], p: Path, ctx: Ctx) -> None:
    """category, has_front, min/max and kinds."""
    name, ty = s.name, s.type
    c = spec.get("category")
    if c is not None:
        if isinstance(c, str):
            c = [c]
        if not isinstance(c, list) or not all(isinstance(x, str) for x in c):
            ctx.err(p + ("category",), f"slot {name!r}: category must be a string or a list of strings")
        else:
            s.category = tuple(c)
    hf = spec.get("has_front")
    if hf is not None:
        if not isinstance(hf, bool):
            ctx.err(p + ("has_front",), f"slot {name!r}: has_front must be true/false")
        else:
            s.has_front = hf
    for key in ("min", "max"):
        x = spec.get(key)
        if x is not None:
            if isinstance(x, bool) or not isinstance(x, int) or x < 1 or x > 8:
                ctx.err(p + (key,), f"slot {name!r}: {key} must be an integer from 1 to 8, got {x!r}")
            else:
                setattr(s, key, x)
    if s.min > s.max:
        ctx.err(p, f"slot {name!r}: min {s.min} > max {s.max}")
    kinds = spec.get("kinds")
    if kinds is not None:
        if ty not in ("region", "spot"):
            ctx.err(p + ("kinds",), f"slot {name!r}: kinds apply to region and spot slots only")
        elif not isinstance(kinds, list) or not all(k in REGION_KINDS for k in kinds) or not kinds:
            ctx.err(p + ("kinds",), f"slot {name!r}: kinds must be a list of {', '.join(REGION_KINDS)}")
        else:
            s.kinds = tuple(kinds)


def _slot_phrases(s: SlotSpec, phr: Any, p: Path, ctx: Ctx) -> None:
    name, ty = s.name, s.type
    if ty not in ("relation", "direction"):
        ctx.err(p + ("phrases",), f"slot {name!r}: phrases apply to relation and direction slots only")
        return
    if not isinstance(phr, dict):
        ctx.err(p + ("phrases",), f"slot {name!r}: phrases must map an id to text or to {{form: text}}")
        return
    for rid, forms in phr.items():
        pp = p + ("phrases", rid)
        if isinstance(forms, str):
            forms = {"prep": forms} if ty == "relation" else {"": forms}
        if not isinstance(forms, dict):
            ctx.err(pp, f"phrases for {rid!r} must be text or a mapping form -> text")
            continue
        comp: dict[str, Seq] = {}
        for form, txt in forms.items():
            if form not in SLOT_FORMS["relation"] or not isinstance(txt, str):
                ctx.err(pp + (form,), f"phrase form {form!r} must be one of prep, cmp, sup, ord, adj, noun with text")
                continue
            try:
                comp[form] = parse(txt)
            except TextSyntaxError as e:
                ctx.err(pp + (form,), f"phrase: {e}")
        s.phrases[str(rid)] = comp
