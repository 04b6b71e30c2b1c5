"""Compile template files (YAML) into typed programs, once, with every error as `file:line: message`.

A template file is a mapping with a `templates:` list. Each template has typed `slots`, a `program` of
steps (qa/ops/, one module per op), and `text` variants (qa/text.py grammar). See docs/templates.md for the language.
Compilation checks everything that can be checked without a scene: op names and arguments, slot and
step references and their types, relation ids, the text placeholders, and the step count (1 to 5).
"""

from __future__ import annotations

import pathlib
from typing import Any

from refspatial_gen.core.errors import RecipeError, RecipeErrors
from refspatial_gen.graph.relations import template_relations
from refspatial_gen.qa import lexicon
from refspatial_gen.qa.ops.base import ANSWER_TYPES
from refspatial_gen.qa.planner import plan_program
from refspatial_gen.qa.program import Ref, SlotSpec, Step, Template
from refspatial_gen.qa.slots import BUILTIN_PLACEHOLDERS, SLOT_FORMS, Ctx, Path, compile_slots
from refspatial_gen.qa.steps import assign_binds, assign_bounds, compile_program, flat_refs
from refspatial_gen.qa.text import Seq, TextSyntaxError, optional_only_placeholders, parse, placeholders
from refspatial_gen.yamlpos import line_of, load_yaml

__all__ = ["MAX_STEPS", "Ref", "SlotSpec", "Step", "Template", "compile_templates", "load_template_file"]
MAX_STEPS = 5
TEMPLATE_KEYS = ("name", "weight", "slots", "program", "text", "instruction", "description", "answer_form")
ANSWER_FORMS = ("letter", "letter_option")  # a choice answer is "(B)" or "(B) no": one form per template


def load_template_file(path: str | pathlib.Path, relation_ids: tuple[str, ...] | None = None) -> list[Template]:
    """Load and compile every template of one file. Raises RecipeErrors listing all problems."""
    file = str(path)
    data, lines = load_yaml(path)
    errors: list[RecipeError] = []
    out = compile_templates(data, file, lines, errors, relation_ids)
    if errors:
        raise RecipeErrors(errors)
    return out


def compile_templates(
    data: Any,
    file: str,
    lines: dict[tuple[Any, ...], int],
    errors: list[RecipeError],
    relation_ids: tuple[str, ...] | None = None,
) -> list[Template]:
    """Compile a parsed template document; problems go to `errors` (nothing raised)."""
    ctx = Ctx(file, lines, errors)
    known_rel = tuple(relation_ids) if relation_ids else template_relations()
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


def _compile_one(item: Any, path: tuple[Any, ...], ctx: Ctx, known_rel: tuple[str, ...]) -> Template | None:
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
    answer_form = item.get("answer_form", "letter")
    if answer_form not in ANSWER_FORMS:
        ctx.err(path + ("answer_form",), f"answer_form must be one of {', '.join(ANSWER_FORMS)}, got {answer_form!r}")
    slots = compile_slots(item.get("slots"), path + ("slots",), ctx, known_rel)
    steps = compile_program(item.get("program"), path + ("program",), ctx, slots, known_rel)
    texts = _compile_texts(item.get("text"), path + ("text",), ctx, required=True)
    instr = (
        _compile_texts(item.get("instruction"), path + ("instruction",), ctx, required=False)
        if item.get("instruction") is not None
        else None
    )
    if not steps:
        return None
    answer_type = steps[-1].out
    if answer_type not in ANSWER_TYPES:
        ctx.err(
            path + ("program", len(steps) - 1),
            f"the program must end in a step giving an answer "
            f"({', '.join(ANSWER_TYPES)}), but {steps[-1].op!r} gives a {answer_type}",
        )
    n_steps = max(1, sum(s.weight for s in steps))  # a plain reference is one step
    if n_steps > MAX_STEPS:
        ctx.err(
            path + ("program",),
            f"step count {n_steps} out of range: questions have 1 to {MAX_STEPS} steps "
            f"(anchors and directional phrases, formats.md)",
        )
    used_in_program = {r.value for s in steps for r in flat_refs(s.args) if r.kind == "slot"}
    text_slots = _text_slots(texts, instr, slots, steps, path, ctx)
    _check_slot_use(slots, used_in_program, text_slots, path, ctx)
    if len(ctx.errors) > n0:
        return None
    literal_rels = sorted(
        {r.value for s in steps for k, r in s.args.items() if k == "relation" and r.kind == "literal"}
    )
    assign_binds(steps, slots)
    assign_bounds(steps)
    t = Template(
        name=name,
        file=ctx.file,
        line=line_of(ctx.lines, path),
        weight=float(weight),
        slots=slots,
        steps=steps,
        texts=texts,
        instructions=instr,
        n_steps=n_steps,
        answer_type=answer_type,
        relations=tuple(literal_rels),
        unbound=tuple(sorted(n for n in text_slots if n not in used_in_program)),
        answer_form=str(answer_form),
    )
    plan_program(t)
    return t


def _text_slots(
    texts: list[Seq], instr: list[Seq] | None, slots: dict[str, SlotSpec], steps: list[Step], path: Path, ctx: Ctx
) -> set[str]:
    """The slots the text variants mention (each placeholder checked against its slot's forms)."""
    text_slots = set()
    for j, seq in enumerate(texts + (instr or [])):
        sub = ("text", j) if j < len(texts) else ("instruction", j - len(texts))
        for ph in sorted(optional_only_placeholders(seq)):
            ctx.err(
                path + sub,
                f"{{{ph}}} appears only inside an optional [...] part: some questions would not say it "
                "(write it outside the brackets)",
            )
        for ph in sorted(placeholders(seq)):
            base, _, form = ph.partition(".")
            if base in BUILTIN_PLACEHOLDERS and not form:
                continue
            if base not in slots:
                ctx.err(path + sub, f"unknown slot {base!r} in text (slots: {', '.join(sorted(slots)) or 'none'})")
                continue
            s = slots[base]
            if form not in SLOT_FORMS[s.type]:
                ctx.err(
                    path + sub,
                    f"{{{ph}}}: a {s.type} slot has no form {form!r} "
                    f"(forms: {', '.join(f or '(plain)' for f in SLOT_FORMS[s.type])})",
                )
                continue
            if s.type == "relation":
                _check_forms(s, "prep" if form in ("", "mod") else form, ctx, path + sub)
            text_slots.add(base)
    for st in steps:  # choice options are written out by {choices} (appended when a variant lacks it)
        opt = st.args.get("options")
        if opt is not None and opt.kind == "list":
            text_slots |= {r.value for r in opt.value if r.kind == "slot"}
    return text_slots


def _check_slot_use(slots: dict[str, SlotSpec], used: set[str], text_slots: set[str], path: Path, ctx: Ctx) -> None:
    """Every slot is used; a slot the program reads is written in the text, and one the text writes that
    carries meaning (an object, a relation...) is read by the program (else its meaning would go unchecked)."""
    for sname, s in slots.items():
        if sname not in used and sname not in text_slots:
            ctx.err(
                path + ("slots", sname), f"slot {sname!r} is declared but used neither in the program nor in the text"
            )
        elif (
            s.type in ("object", "anchor", "relation", "direction", "region", "spot")
            and sname in used
            and sname not in text_slots
        ):
            ctx.err(path + ("text",), f"slot {sname!r} is used by the program but no text variant mentions it")
    for sname in sorted(text_slots):
        if sname in used:
            continue
        if slots[sname].type in ("object", "anchor", "relation", "region", "spot", "direction"):
            ctx.err(
                path + ("slots", sname),
                f"slot {sname!r} appears only in the text; the program must use it (its meaning would not be checked)",
            )


def _check_forms(s: SlotSpec, form: str, ctx: Ctx, path: tuple[Any, ...]) -> None:
    for rel in s.choices or ():
        if form in s.phrases.get(rel, {}):
            continue
        if form not in lexicon.RELATION_FORMS.get(rel, {}):
            ctx.err(
                path,
                f"relation {rel!r} (slot {s.name!r}) has no {form!r} wording; add phrases: "
                f"{{{rel}: {{{form}: ...}}}} to the slot or drop it from the choices",
            )


def _compile_texts(v: Any, path: tuple[Any, ...], ctx: Ctx, required: bool) -> list[Seq]:
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
