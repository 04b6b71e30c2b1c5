"""Compile template files (YAML) into typed programs, once, with every error as `file:line: message`.

A template file is a mapping with a `templates:` list. Each template has typed `slots`, a `program` of
steps (qa/ops.py), and `text` variants (qa/text.py grammar). See docs/templates.md for the language.
Compilation checks everything that can be checked without a scene: op names and arguments, slot and
step references and their types, relation ids, the text placeholders, and the step count (1 to 5).
"""

from __future__ import annotations

from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from refspatial_gen.core.errors import RecipeError, RecipeErrors
from refspatial_gen.qa import lexicon, ops
from refspatial_gen.qa.text import Seq, TextSyntaxError, parse, placeholders
from refspatial_gen.yamlpos import line_of, load_yaml

# The 31 canonical relation ids (relations.md) plus the extra ones the graph records.
RELATION_IDS = (
    "left", "right", "close", "far", "depth", "above_world", "below_world", "above_image", "below_image", "tall",
    "short", "between", "rotation_horizontal", "rotation_vertical", "free_space", "corner", "edge", "angle",
    "distance", "front", "behind", "big", "small", "inside", "outside", "facing", "facing_away", "wide", "thin",
    "touching", "far_from",
)
EXTRA_RELATIONS = ("next_to", "on")
MAX_STEPS = 5
TEMPLATE_KEYS = ("name", "weight", "slots", "program", "text", "instruction", "description")
SLOT_KEYS = ("type", "choices", "category", "has_front", "min", "max", "kinds", "phrases", "description")
SLOT_FORMS = {  # placeholder suffixes each slot type renders
    "object": ("", "category", "color"), "anchor": ("", "category", "color"),
    "relation": ("", "prep", "cmp", "sup", "ord", "adj", "noun"), "direction": ("",), "surface": ("",),
    "number": ("", "value"), "category": ("", "plural"), "color": ("",), "region": ("", "surface"),
    "spot": ("", "surface", "label"),
}
BUILTIN_PLACEHOLDERS = ("choices", "instruction")


@dataclass(frozen=True)
class Ref:
    """An argument: a slot, an earlier step's output, a literal, or the previous step (`None` value)."""

    kind: str  # "slot" | "step" | "literal" | "prev" | "all" | "list"
    value: Any = None


@dataclass
class SlotSpec:
    name: str
    type: str
    line: int | None
    choices: tuple | None = None
    category: tuple | None = None
    has_front: bool | None = None
    min: int = 1
    max: int = 3
    kinds: tuple | None = None
    phrases: dict[str, dict[str, Seq]] = field(default_factory=dict)


@dataclass
class Step:
    index: int
    op: str
    name: str
    args: dict[str, Ref]
    out: str
    line: int | None
    weight: int
    binds: tuple[str, ...] = ()  # slots first needed at this step (bound by the search just before it runs)
    min_out: int = 1  # a set this step gives must hold at least this many objects (later steps narrow it)
    exact_one: bool = False  # the set this step gives is the described object: exactly one


@dataclass
class Template:
    name: str
    file: str
    line: int | None
    weight: float
    slots: dict[str, SlotSpec]
    steps: list[Step]
    texts: list[Seq]
    instructions: list[Seq] | None
    n_steps: int
    answer_type: str
    relations: tuple[str, ...]  # literal relation ids (slot relations are added per instance)
    family: str = ""
    unbound: tuple[str, ...] = ()  # slots only used in text (bound before rendering)


class _Ctx:
    def __init__(self, file: str, lines: dict, errors: list[RecipeError]) -> None:
        self.file, self.lines, self.errors = file, lines, errors

    def err(self, path: tuple, msg: str) -> None:
        self.errors.append(RecipeError(self.file, line_of(self.lines, path), msg))


def load_template_file(path: str | Path, relation_ids: tuple[str, ...] | None = None) -> list[Template]:
    """Load and compile every template of one file. Raises RecipeErrors listing all problems."""
    file = str(path)
    data, lines = load_yaml(path)
    errors: list[RecipeError] = []
    out = compile_templates(data, file, lines, errors, relation_ids)
    if errors:
        raise RecipeErrors(errors)
    return out


def compile_templates(data: Any, file: str, lines: dict, errors: list[RecipeError],
                      relation_ids: tuple[str, ...] | None = None) -> list[Template]:
    """Compile a parsed template document; problems go to `errors` (nothing raised)."""
    ctx = _Ctx(file, lines, errors)
    known_rel = tuple(relation_ids or RELATION_IDS) + EXTRA_RELATIONS
    if not isinstance(data, dict):
        ctx.err((), "a template file must be a mapping with a 'templates:' list")
        return []
    for k in data:
        if k not in ("templates", "description"):
            ctx.err((k,), f"unknown key {k!r} in template file (known: description, templates)")
    items = data.get("templates")
    if not isinstance(items, list) or not items:
        ctx.err(("templates",), "'templates' must be a non-empty list")
        return []
    out: list[Template] = []
    seen: dict[str, int] = {}
    for i, item in enumerate(items):
        t = _compile_one(item, ("templates", i), ctx, known_rel)
        if t is None:
            continue
        if t.name in seen:
            ctx.err(("templates", i, "name"), f"duplicate template name {t.name!r}")
            continue
        seen[t.name] = i
        out.append(t)
    return out


def _compile_one(item: Any, path: tuple, ctx: _Ctx, known_rel: tuple[str, ...]) -> Template | None:
    n0 = len(ctx.errors)
    if not isinstance(item, dict):
        ctx.err(path, f"a template must be a mapping, got {type(item).__name__}")
        return None
    for k in item:
        if k not in TEMPLATE_KEYS:
            ctx.err(path + (k,), f"unknown key {k!r} in template (known: {', '.join(TEMPLATE_KEYS)})")
    name = item.get("name")
    if not isinstance(name, str) or not name.strip():
        ctx.err(path + ("name",), "template needs a 'name' (a string)")
        name = f"template_{path[-1]}"
    weight = item.get("weight", 1.0)
    if isinstance(weight, bool) or not isinstance(weight, (int, float)) or not weight >= 0:
        ctx.err(path + ("weight",), f"weight must be a number >= 0, got {weight!r}")
        weight = 1.0
    slots = _compile_slots(item.get("slots"), path + ("slots",), ctx, known_rel)
    steps = _compile_program(item.get("program"), path + ("program",), ctx, slots, known_rel)
    texts = _compile_texts(item.get("text"), path + ("text",), ctx, required=True)
    instr = _compile_texts(item.get("instruction"), path + ("instruction",), ctx, required=False) \
        if item.get("instruction") is not None else None
    if not steps:
        return None
    answer_type = steps[-1].out
    if answer_type not in ops.ANSWER_TYPES:
        ctx.err(path + ("program", len(steps) - 1), f"the program must end in a step giving an answer "
                f"({', '.join(ops.ANSWER_TYPES)}), but {steps[-1].op!r} gives a {answer_type}")
    n_steps = ops.count_steps([(s.op, s.args) for s in steps])
    if n_steps > MAX_STEPS:
        ctx.err(path + ("program",), f"step count {n_steps} out of range: questions have 1 to {MAX_STEPS} steps "
                f"(anchors and directional phrases, formats.md)")
    used_in_program = {r.value for s in steps for r in _flat_refs(s.args) if r.kind == "slot"}
    text_slots = set()
    for j, seq in enumerate(texts + (instr or [])):
        sub = ("text", j) if j < len(texts) else ("instruction", j - len(texts))
        for ph in sorted(placeholders(seq)):
            base, _, form = ph.partition(".")
            if base in BUILTIN_PLACEHOLDERS and not form:
                continue
            if base not in slots:
                ctx.err(path + sub, f"unknown slot {base!r} in text (slots: {', '.join(sorted(slots)) or 'none'})")
                continue
            s = slots[base]
            if form not in SLOT_FORMS[s.type]:
                ctx.err(path + sub, f"{{{ph}}}: a {s.type} slot has no form {form!r} "
                        f"(forms: {', '.join(f or '(plain)' for f in SLOT_FORMS[s.type])})")
                continue
            if s.type == "relation":
                _check_forms(s, form or "prep", ctx, path + sub)
            text_slots.add(base)
    for st in steps:  # choice options are written out by {choices} (appended when a variant lacks it)
        opt = st.args.get("options")
        if opt is not None and opt.kind == "list":
            text_slots |= {r.value for r in opt.value if r.kind == "slot"}
    for sname, s in slots.items():
        if sname not in used_in_program and sname not in text_slots:
            ctx.err(path + ("slots", sname), f"slot {sname!r} is declared but used neither in the program nor in the text")
        elif s.type in ("object", "anchor", "relation", "direction", "region", "spot") and sname in used_in_program \
                and sname not in text_slots:
            ctx.err(path + ("text",), f"slot {sname!r} is used by the program but no text variant mentions it")
    for sname in sorted(text_slots):
        if sname in used_in_program:
            continue
        if slots[sname].type in ("object", "anchor", "relation", "region", "spot", "direction"):
            ctx.err(path + ("slots", sname), f"slot {sname!r} appears only in the text; the program must use it "
                    "(its meaning would not be checked)")
    for j, seq in enumerate(texts):
        for ph in placeholders(seq):
            base = ph.partition(".")[0]
            if base in slots and base in used_in_program and slots[base].type != "number":
                pass
    if len(ctx.errors) > n0:
        return None
    literal_rels = sorted({r.value for s in steps for k, r in s.args.items()
                           if k == "relation" and r.kind == "literal"})
    _assign_binds(steps, slots)
    _assign_bounds(steps)
    return Template(name=name, file=ctx.file, line=line_of(ctx.lines, path), weight=float(weight), slots=slots,
                    steps=steps, texts=texts, instructions=instr, n_steps=n_steps, answer_type=answer_type,
                    relations=tuple(literal_rels),
                    unbound=tuple(sorted(n for n in text_slots if n not in used_in_program)))


def _check_forms(s: SlotSpec, form: str, ctx: _Ctx, path: tuple) -> None:
    for rel in s.choices or ():
        if form in s.phrases.get(rel, {}):
            continue
        if form not in lexicon.RELATION_FORMS.get(rel, {}):
            ctx.err(path, f"relation {rel!r} (slot {s.name!r}) has no {form!r} wording; add phrases: "
                    f"{{{rel}: {{{form}: ...}}}} to the slot or drop it from the choices")


def _compile_texts(v: Any, path: tuple, ctx: _Ctx, required: bool) -> list[Seq]:
    if isinstance(v, str):
        v = [v]
    if not isinstance(v, list) or (required and not v):
        ctx.err(path, "text must be a string or a non-empty list of strings")
        return []
    out = []
    for j, s in enumerate(v):
        if not isinstance(s, str) or not s.strip():
            ctx.err(path + (j,), f"text variant must be a non-empty string, got {type(s).__name__}")
            continue
        try:
            out.append(parse(s))
        except TextSyntaxError as e:
            ctx.err(path + (j,), f"text variant: {e}")
    return out


def _compile_slots(v: Any, path: tuple, ctx: _Ctx, known_rel: tuple[str, ...]) -> dict[str, SlotSpec]:
    if v is None:
        return {}
    if not isinstance(v, dict):
        ctx.err(path, f"slots must be a mapping of name -> type, got {type(v).__name__}")
        return {}
    out: dict[str, SlotSpec] = {}
    for name, spec in v.items():
        p = path + (name,)
        if not isinstance(name, str) or not name.isidentifier():
            ctx.err(p, f"slot name {name!r} must be an identifier")
            continue
        if name in BUILTIN_PLACEHOLDERS or name in known_rel or name == "all":
            ctx.err(p, f"slot name {name!r} is reserved")
            continue
        if isinstance(spec, str):
            spec = {"type": spec}
        if not isinstance(spec, dict):
            ctx.err(p, f"slot {name!r} must be a type name or a mapping, got {type(spec).__name__}")
            continue
        for k in spec:
            if k not in SLOT_KEYS:
                ctx.err(p + (k,), f"unknown key {k!r} in slot {name!r} (known: {', '.join(SLOT_KEYS)})")
        ty = spec.get("type")
        if ty not in ops.SLOT_TYPES:
            ctx.err(p + ("type",), f"slot {name!r}: unknown slot type {ty!r} (known: {', '.join(ops.SLOT_TYPES)})")
            continue
        s = SlotSpec(name, ty, line_of(ctx.lines, p))
        ch = spec.get("choices")
        if ch is not None:
            if not isinstance(ch, list) or not ch or not all(isinstance(c, (str, int)) and not isinstance(c, bool)
                                                               for c in ch):
                ctx.err(p + ("choices",), f"slot {name!r}: choices must be a non-empty list of names")
            else:
                s.choices = tuple(ch)
                if ty == "relation":
                    for j, c in enumerate(ch):
                        if c not in known_rel:
                            ctx.err(p + ("choices", j), f"unknown relation {c!r} (known: {', '.join(known_rel)})")
                elif ty == "direction":
                    allowed = ops.FREE_KINDS + tuple(x for pair in ops.TURN_AXES.values() for x in pair)
                    for j, c in enumerate(ch):
                        if c not in allowed:
                            ctx.err(p + ("choices", j), f"unknown direction {c!r} (known: {', '.join(allowed)})")
                elif ty == "number":
                    if not all(isinstance(c, int) and c >= 1 for c in ch):
                        ctx.err(p + ("choices",), f"slot {name!r}: number choices must be integers >= 1")
        for key in ("category",):
            c = spec.get(key)
            if c is not None:
                if isinstance(c, str):
                    c = [c]
                if not isinstance(c, list) or not all(isinstance(x, str) for x in c):
                    ctx.err(p + (key,), f"slot {name!r}: {key} must be a string or a list of strings")
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
            elif not isinstance(kinds, list) or not all(k in ops.REGION_KINDS for k in kinds) or not kinds:
                ctx.err(p + ("kinds",), f"slot {name!r}: kinds must be a list of {', '.join(ops.REGION_KINDS)}")
            else:
                s.kinds = tuple(kinds)
        phr = spec.get("phrases")
        if phr is not None:
            if ty not in ("relation", "direction"):
                ctx.err(p + ("phrases",), f"slot {name!r}: phrases apply to relation and direction slots only")
            elif not isinstance(phr, dict):
                ctx.err(p + ("phrases",), f"slot {name!r}: phrases must map an id to text or to {{form: text}}")
            else:
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
                            ctx.err(pp + (form,), f"phrase form {form!r} must be one of prep, cmp, sup, ord, adj, noun "
                                    "with text")
                            continue
                        try:
                            comp[form] = parse(txt)
                        except TextSyntaxError as e:
                            ctx.err(pp + (form,), f"phrase: {e}")
                    s.phrases[str(rid)] = comp
        out[name] = s
    return out


def _flat_refs(args: dict[str, Ref]) -> list[Ref]:
    out = []
    for r in args.values():
        if r.kind == "list":
            out.extend(r.value)
        else:
            out.append(r)
    return out


def _compile_program(v: Any, path: tuple, ctx: _Ctx, slots: dict[str, SlotSpec], known_rel) -> list[Step]:
    if not isinstance(v, list) or not v:
        ctx.err(path, "program must be a non-empty list of steps")
        return []
    steps: list[Step] = []
    names: dict[str, Step] = {}
    rel_uses: dict[str, set[str]] = {}
    for i, raw in enumerate(v):
        p = path + (i,)
        if not isinstance(raw, dict):
            ctx.err(p, f"a step must be a mapping with 'op:', got {type(raw).__name__}")
            return []
        op = raw.get("op")
        if not isinstance(op, str) or op not in ops.OPS:
            ctx.err(p + ("op",), f"unknown op {op!r} (known: {', '.join(sorted(ops.OPS))})")
            return []
        spec = ops.OPS[op]
        sname = raw.get("as", f"step{i + 1}")
        if not isinstance(sname, str) or not sname.isidentifier() or sname in slots or sname in names:
            ctx.err(p + ("as",), f"step name {sname!r} must be a new identifier (not a slot or earlier step)")
            return []
        args: dict[str, Ref] = {}
        ok = True
        for k in raw:
            if k in ("op", "as"):
                continue
            if k not in spec.args:
                ctx.err(p + (k,), f"op {op!r} has no argument {k!r} (arguments: {', '.join(spec.args)})")
                ok = False
        for k, a in spec.args.items():
            if k not in raw or raw[k] is None:
                if a.required:
                    ctx.err(p, f"op {op!r} needs argument {k!r}")
                    ok = False
                continue
            r = _resolve_arg(raw[k], a.kind, spec, p + (k,), ctx, slots, names, known_rel, rel_uses)
            if r is None:
                ok = False
            else:
                args[k] = r
        if not ok:
            return []
        if not _check_op_shape(op, args, p, ctx, steps):
            return []
        st = Step(i, op, sname, args, spec.out, line_of(ctx.lines, p), ops.step_weight(op, args))
        steps.append(st)
        names[sname] = st
    for sname, allowed in rel_uses.items():
        s = slots[sname]
        if s.choices is None:
            s.choices = tuple(r for r in allowed if r in known_rel)
        else:
            for r in s.choices:
                if r not in allowed and r in known_rel:
                    ctx.err(path, f"relation {r!r} (slot {sname!r}) cannot be used by every step that uses the slot")
    return steps


def _check_op_shape(op: str, args: dict[str, Ref], p: tuple, ctx: _Ctx, prior: list[Step]) -> bool:
    if op == "free_space":
        n = sum(k in args for k in ("anchor", "anchors", "region"))
        if n != 1:
            ctx.err(p, "free_space needs exactly one of anchor, anchors (two objects) or region")
            return False
        if "region" not in args and "anchors" not in args and "direction" not in args:
            ctx.err(p, "free_space with an anchor needs a direction")
            return False
    if op in ("between",) or (op == "free_space" and "anchors" in args):
        r = args.get("anchors")
        if r is not None and len(r.value) != 2:
            ctx.err(p + ("anchors",), "anchors must list exactly two objects")
            return False
    if op == "choose":
        r = args["options"]
        if r.kind == "list" and len(r.value) < 2:
            ctx.err(p + ("options",), "choose needs at least two options")
            return False
    if op in ("superlative", "compare", "choose"):
        rel = args.get("relation")
        if rel is not None and rel.kind == "literal" and rel.value in ops.ANCHORED and "anchor" not in args:
            ctx.err(p + ("relation",), f"relation {rel.value!r} compares distances to an anchor: add anchor:")
            return False
    if op == "measure":
        q = args["quantity"].value
        n = ops.QUANTITIES[q][0]
        if "of" not in args and not (prior and prior[-1].out in (ops.OBJECT, ops.SET)):
            ctx.err(p, "measure needs of: (an object)")
            return False
        if n == 2 and "to" not in args:
            ctx.err(p, f"measure {q} needs to: (a second object)")
            return False
        if n == 1 and "to" in args:
            ctx.err(p + ("to",), f"measure {q} takes one object")
            return False
    if op in ("locate",) and "of" not in args and not (prior and prior[-1].out in (ops.SET, ops.OBJECT)):
        ctx.err(p, "locate needs of: (an object) or a preceding step that selects objects")
        return False
    return True


def _resolve_arg(v: Any, kind: str, spec: ops.OpSpec, p: tuple, ctx: _Ctx, slots: dict[str, SlotSpec],
                 names: dict[str, Step], known_rel, rel_uses: dict[str, set[str]]) -> Ref | None:
    def slot_or_step(x: Any, want_slot: tuple[str, ...], want_step: tuple[str, ...], what: str) -> Ref | None:
        if not isinstance(x, str):
            ctx.err(p, f"{what} must be a slot or step name, got {type(x).__name__} {x!r}")
            return None
        if x in slots:
            if slots[x].type not in want_slot:
                ctx.err(p, f"{x!r} is a {slots[x].type} slot; {spec.name}.{p[-1]} needs {what}")
                return None
            return Ref("slot", x)
        if x in names:
            if names[x].out not in want_step:
                ctx.err(p, f"step {x!r} gives a {names[x].out}; {spec.name}.{p[-1]} needs {what}")
                return None
            return Ref("step", x)
        ctx.err(p, f"unknown slot {x!r} (slots: {', '.join(sorted(slots)) or 'none'}; steps: "
                f"{', '.join(names) or 'none'})")
        return None

    if kind == "set":
        if v == "all":
            return Ref("all")
        return slot_or_step(v, (), (ops.SET,), "a set of objects")
    if kind == "object":  # a step giving a set is accepted: it must hold exactly one object at run time
        return slot_or_step(v, ("object", "anchor"), (ops.OBJECT, ops.SET), "an object")
    if kind == "objects" or kind == "options":
        if kind == "options" and isinstance(v, str) and v in names and names[v].out == ops.MARKS:
            return Ref("step", v)
        if not isinstance(v, list):
            ctx.err(p, f"{spec.name}.{p[-1]} must be a list of objects")
            return None
        refs = []
        for j, x in enumerate(v):
            r = slot_or_step(x, ("object", "anchor"), (ops.OBJECT,), "an object")
            if r is None:
                return None
            refs.append(r)
        return Ref("list", tuple(refs))
    if kind == "relation":
        if isinstance(v, str) and v in slots:
            if slots[v].type != "relation":
                ctx.err(p, f"{v!r} is a {slots[v].type} slot; {spec.name}.relation needs a relation")
                return None
            allowed = set(spec.relations)
            rel_uses[v] = rel_uses.get(v, set(allowed)) & allowed if v in rel_uses else allowed
            return Ref("slot", v)
        if not isinstance(v, str) or v not in known_rel:
            ctx.err(p, f"unknown relation {v!r} (known: {', '.join(known_rel)})")
            return None
        if v not in spec.relations:
            ctx.err(p, f"relation {v!r} cannot be used with {spec.name} (allowed: {', '.join(spec.relations)})")
            return None
        return Ref("literal", v)
    if kind in ("direction", "surface", "region", "spot", "number", "category", "color"):
        if isinstance(v, str) and v in slots:
            if slots[v].type != kind:
                ctx.err(p, f"{v!r} is a {slots[v].type} slot; {spec.name}.{p[-1]} needs a {kind}")
                return None
            return Ref("slot", v)
        if kind == "direction" and isinstance(v, str) and v in ops.FREE_KINDS:
            return Ref("literal", v)
        if kind == "number" and isinstance(v, int) and not isinstance(v, bool) and 1 <= v <= 8:
            return Ref("literal", v)
        if kind in ("surface", "category", "color") and isinstance(v, str) and v:
            return Ref("literal", v)
        ctx.err(p, f"unknown slot {v!r}: {spec.name}.{p[-1]} needs a {kind} slot"
                + (" or literal" if kind not in ("region", "spot") else ""))
        return None
    if kind == "bools":
        if not isinstance(v, list) or len(v) < 2:
            ctx.err(p, "all.of must list at least two earlier yes/no steps")
            return None
        refs = []
        for x in v:
            r = slot_or_step(x, (), (ops.BOOL,), "a yes/no step")
            if r is None:
                return None
            refs.append(r)
        return Ref("list", tuple(refs))
    choices = {"quantity": tuple(ops.QUANTITIES), "style": ("box", "point"), "axis": tuple(ops.TURN_AXES),
               "mode": ("most", "which")}
    if kind in choices:
        if v not in choices[kind]:
            ctx.err(p, f"{spec.name}.{p[-1]} must be one of {', '.join(choices[kind])}, got {v!r}")
            return None
        return Ref("literal", v)
    if kind == "int":
        if isinstance(v, bool) or not isinstance(v, int) or not 2 <= v <= 6:
            ctx.err(p, f"{spec.name}.{p[-1]} must be an integer from 2 to 6, got {v!r}")
            return None
        return Ref("literal", v)
    ctx.err(p, f"cannot read argument {p[-1]!r}")
    return None


def _assign_binds(steps: list[Step], slots: dict[str, SlotSpec]) -> None:
    seen: set[str] = set()
    for st in steps:
        b = []
        for r in _flat_refs(st.args):
            if r.kind == "slot" and r.value not in seen:
                seen.add(r.value)
                b.append(r.value)
        st.binds = tuple(b)


NARROWING = ("relate", "between", "at")


def _assign_bounds(steps: list[Step]) -> None:
    """Early pruning bounds: every later narrowing step must remove at least one object (else it is
    degenerate), a superlative or ordinal needs two candidates, and the set a single-object consumer reads
    must hold exactly one object."""
    for i, st in enumerate(steps):
        if st.out != ops.SET:
            continue
        need = 1
        j = i + 1
        while j < len(steps) and steps[j].args.get("in") is None and steps[j].op in NARROWING:
            need += 1
            j += 1
        nxt = steps[j] if j < len(steps) else None
        if nxt is not None and nxt.op in ("superlative", "ordinal") and nxt.args.get("in") is None:
            need += 1
        st.min_out = need
        if j == i + 1 and nxt is not None and nxt.op in ("locate", "measure") and nxt.args.get("of") is None:
            st.exact_one = True
        for later in steps[i + 1:]:
            for r in later.args.values():
                rs = r.value if r.kind == "list" else (r,)
                for x in rs:
                    if isinstance(x, Ref) and x.kind == "step" and x.value == st.name and later.op in (
                            "compare", "measure", "locate", "choose"):
                        st.exact_one = True
