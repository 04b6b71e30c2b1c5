"""The record of a QA pair: answer text and structure, question text, the executed program, key steps,
reasoning trace and checks (the QAPair that shards store and `verify` re-checks).

Why a plan per template: most of a record's shape is fixed by the template (which relations it names, how
each argument is written, which steps name the answer's targets); `plan_record` derives it at compile time,
so building a record reads the instance's values only.
"""

from __future__ import annotations

from typing import Any, NamedTuple

import numpy as np

from refspatial_gen.core.model import QAPair
from refspatial_gen.qa import lexicon
from refspatial_gen.qa.index import Reject, SceneIndex
from refspatial_gen.qa.keysteps import check_key_phrases, key_steps, one
from refspatial_gen.qa.ops.base import BOOL, NUMBER
from refspatial_gen.qa.ops.measure import QUANTITIES
from refspatial_gen.qa.program import Ref, Step, Template
from refspatial_gen.qa.render import LETTERS, fmt_angle, fmt_choices, fmt_length, fmt_points, fmt_trace, fmt_turn
from refspatial_gen.qa.sample_rng import SampleRng
from refspatial_gen.qa.text import placeholders, render
from refspatial_gen.qa.values import Context, NumberValue, OptionValue, PointValue
from refspatial_gen.qa.wording import Renderer, parsed

CHECKS = ("unique_references", "nondegenerate", "outside_margin", "balanced")


class RecordPlan(NamedTuple):
    """What a record needs from a template that does not depend on the instance."""

    relations: frozenset[str]  # relation ids fixed by the program (literal relations, between, quantities...)
    relation_slots: tuple[str, ...]  # relation slots: their bound value is a relation of the question
    region_refs: tuple[str, ...]  # region slots whose kind is a relation
    spot_refs: tuple[str, ...]  # spot slots whose kind (corner, edge) is a relation
    program: tuple[Any, ...]  # per step: (step, its args, implicit "in" (prev step name, "" = all, None = none),
    #                 implicit "of" ((prev step name,) or None))
    targets: dict[str, tuple[Ref, ...]]  # answer type -> the slot/step arguments naming its targets
    mark_style: str  # the style of the program's drawn marks ("box" without a mark step)


def plan_record(t: Template) -> RecordPlan:
    rel = set(t.relations)
    regions: list[str] = []
    spots: list[str] = []
    targets: dict[str, list[Ref]] = {}
    for st in t.steps:
        rec = st.impl.recorded(st)
        rel.update(rec.relations)
        regions += rec.region_slots
        spots += rec.spot_slots
        if st.impl.targets_for:
            targets.setdefault(st.impl.targets_for, []).extend(
                r for k in st.impl.target_args if (r := st.args.get(k)) is not None and r.kind in ("slot", "step")
            )
    program: list[tuple[Step, tuple[tuple[str, int, Any], ...], str | None, tuple[str | None] | None]] = []
    prev_name = None
    for st in t.steps:
        default_in: str | None = None
        if st.args.get("in") is None and st.impl.args.get("in") is not None:
            default_in = prev_name or ""
        default_of = (prev_name,) if st.impl.implicit_of and "of" not in st.args else None
        program.append((st, _arg_plan(t, st), default_in, default_of))
        prev_name = st.name
    marks = [s for st in t.steps if (s := st.impl.mark_style(st)) is not None]
    return RecordPlan(
        frozenset(rel),
        tuple(n for n, s in t.slots.items() if s.type == "relation"),
        tuple(regions),
        tuple(spots),
        tuple(program),
        {k: tuple(v) for k, v in targets.items()},
        marks[0] if marks else "box",
    )


class Answer(NamedTuple):
    text: str
    struct: dict[str, Any]
    choices: str  # the options as the question writes them ("" when none)
    targets: list[int]


def _point_answer(ans: PointValue, idx: SceneIndex) -> Answer:
    if ans.region is not None:
        r = ans.region
        poly, world = idx.region_rounded(r)
        region: dict[str, Any] = {
            "kind": "region",
            "points": [list(ans.point)],
            "region": {
                "surface_id": r.surface_id,
                "kind": r.kind,
                "anchors": list(r.anchors),
                "label": r.label,
                "z": round(float(r.z), 6),
                "polygon_xy": [list(p) for p in poly],
                "point_world": list(world),
            },
        }
        return Answer(
            fmt_points([ans.point]), region, "", [int(a) for a in r.anchors if isinstance(a, (int, np.integer))]
        )
    oid = int(ans.object_id)  # type: ignore[arg-type]  # a point without a region names its object
    struct: dict[str, Any] = {"kind": "points", "points": [list(ans.point)], "object_ids": [oid]}
    return Answer(fmt_points([ans.point]), struct, "", [oid])


def _bool_answer(raw: bool, t: Template, env: dict[str, Any], rng: SampleRng) -> Answer:
    order = ["yes", "no"] if rng.integers(2) == 0 else ["no", "yes"]
    k = order.index("yes" if raw else "no")
    choices = fmt_choices(order)
    text = f"({LETTERS[k]}) {order[k]}" if t.answer_form == "letter_option" else f"({LETTERS[k]})"
    struct = {"kind": "choice", "options": order, "letter": LETTERS[k], "answer": order[k]}
    refs = t.program.record.targets.get(BOOL, ())
    return Answer(text, struct, choices, sorted({one(env[r.value]) for r in refs}))


def _option_answer(raw: OptionValue, t: Template, idx: SceneIndex, rng: SampleRng, view: int) -> Answer:
    n = len(raw.options)
    perm = list(range(n)) if raw.marks else [int(x) for x in rng.permutation(n)]  # marks: already random order
    opts = [raw.options[p] for p in perm]
    k = perm.index(raw.correct)
    texts = ["" for _ in opts] if raw.marks else [o if isinstance(o, str) else idx.phrase[o] for o in opts]
    choices = fmt_choices(texts)
    text = f"({LETTERS[k]}) {texts[k]}" if t.answer_form == "letter_option" and texts[k] else f"({LETTERS[k]})"
    struct: dict[str, Any] = {
        "kind": "choice",
        "options": texts,
        "letter": LETTERS[k],
        "answer": texts[k] if texts[k] else LETTERS[k],
    }
    targets: list[int] = []
    if not isinstance(opts[0], str):
        struct["option_ids"] = [int(o) for o in opts]
        targets = [int(opts[k])]
    if raw.marks:
        style = t.program.record.mark_style
        struct["style"] = style
        struct["marks"] = [
            {
                "label": LETTERS[i],
                "object_id": int(o),
                "style": style,
                "view": view,
                "box": _box(idx, o),
                "point": list(idx.point(o)),
            }
            for i, o in enumerate(opts)
        ]
    return Answer(text, struct, choices, targets)


def _box(idx: SceneIndex, o: int) -> list[float] | None:
    b = idx.objects[o].bbox2d
    return None if b is None else [round(float(x), 1) for x in b]


def _number_answer(raw: NumberValue, t: Template, env: dict[str, Any], rng: SampleRng) -> Answer:
    q = raw.quantity
    kind = QUANTITIES[q][2]
    if kind == "length":
        text, unit = fmt_length(raw.value, rng), "m"  # the written unit by magnitude; the struct stays in metres
    elif kind == "angle":
        text, unit = fmt_angle(raw.value), "rad"
    else:
        text, unit = fmt_turn(raw.value, q.split("_")[1]), "rad"
    struct = {"kind": "number", "value": round(raw.value, 6), "unit": unit, "quantity": q}
    targets = sorted({one(env[r.value]) for r in t.program.record.targets.get(NUMBER, ())})
    if not targets:
        prev = env[t.steps[-2].name] if len(t.steps) > 1 else None
        if isinstance(prev, frozenset) and len(prev) == 1:
            prev = next(iter(prev))
        if isinstance(prev, (int, np.integer)):
            targets = [int(prev)]
    return Answer(text, struct, "", targets)


def _answer(t: Template, env: dict[str, Any], ans: Any, idx: SceneIndex, rng: SampleRng, view: int) -> Answer:
    raw = env[t.steps[-1].name]
    if isinstance(ans, PointValue):
        return _point_answer(ans, idx)
    if isinstance(raw, bool):
        return _bool_answer(raw, t, env, rng)
    if isinstance(raw, OptionValue):
        return _option_answer(raw, t, idx, rng, view)
    if isinstance(raw, NumberValue):
        return _number_answer(raw, t, env, rng)
    raise Reject("answer_type")


def _question(t: Template, env: dict[str, Any], ans: Any, ctx: Context, rng: SampleRng, choices: str) -> str:
    if isinstance(ans, PointValue):
        instr_seq = (
            t.instructions[int(rng.integers(len(t.instructions)))]
            if t.instructions
            else parsed(lexicon.POINT_INSTRUCTIONS[int(rng.integers(len(lexicon.POINT_INSTRUCTIONS)))])
        )
    else:
        instr_seq = None
    variant = t.texts[int(rng.integers(len(t.texts)))]
    ph = placeholders(variant)
    rend = Renderer(t, env, ctx, rng, choices, "")
    if instr_seq is not None:
        rend.instruction = render(instr_seq, rend, rng)
    question = render(variant, rend, rng)
    if choices and "choices" not in ph:
        question = f"{question} {choices}"
    if instr_seq is not None and "instruction" not in ph:
        question = f"{question} {rend.instruction}"
    return question


def _program_record(t: Template, env: dict[str, Any], idx: SceneIndex) -> list[dict[str, Any]]:
    program = []
    phrase = idx.phrase
    for st, arg_plan, default_in, default_of in t.program.record.program:
        args: dict[str, Any] = {}
        for k, mode, p in arg_plan:
            if mode == 0:
                args[k] = p
            elif mode == 1:
                args[k] = {"step": p}
            elif mode == 2:
                v = env[p]
                args[k] = {"slot": p, "object": int(v), "phrase": phrase[v]}
            else:
                args[k] = _ref_json(p, env, t, idx)
        if default_in is not None:
            args["in"] = {"step": default_in} if default_in else "all"
        if default_of is not None:
            args["of"] = {"step": default_of[0]}
        program.append({"op": st.op, "as": st.name, "args": args, "out": _out_json(env[st.name]), "weight": st.weight})
    return program


def build_pair(
    t: Template,
    env: dict[str, Any],
    ans: Any,
    ctx: Context,
    rng: SampleRng,
    frame_ids: list[str],
    qa_id: str,
    view: int = 0,
) -> QAPair:
    """The QA pair's record. `view` is the asked frame's position in the sample's frames: drawn marks name it,
    so the exporter and the preview draw them on that image."""
    idx = ctx.idx
    plan = t.program.record
    relations = set(plan.relations)
    for name in plan.relation_slots:
        if name in env:
            relations.add(env[name])
    for name in plan.region_refs:
        relations.add(env[name].kind)
    for name in plan.spot_refs:
        relations.add(env[name][0])
    a = _answer(t, env, ans, idx, rng, view)
    question = _question(t, env, ans, ctx, rng, a.choices)
    keys = key_steps(t, env, ans, idx)
    check_key_phrases(keys, a.struct, a.targets, idx)
    trace = fmt_trace(keys, a.text) if t.n_steps >= 2 else ""
    checks = list(CHECKS)
    if isinstance(ans, PointValue):
        checks.append("free_point" if ans.region is not None else "point_in_mask")
    return QAPair(
        qa_id=qa_id,
        family=t.family,
        template=f"{t.family}/{t.name}",
        question=question,
        answer=a.text,
        answer_struct=a.struct,
        relations=sorted(relations),
        steps=t.n_steps,
        frame_ids=list(frame_ids),
        image_size=(idx.W, idx.H),
        program=_program_record(t, env, idx),
        trace=trace,
        key_steps=keys,
        checks=checks,
        targets=a.targets,
    )


def _ref_json(ref: Ref | None, env: dict[str, Any], t: Template, idx: SceneIndex) -> Any:
    if ref is None:
        return {"step": "prev"}
    if ref.kind == "list":
        return [_ref_json(r, env, t, idx) for r in ref.value]
    if ref.kind == "all":
        return "all"
    if ref.kind == "step":
        return {"step": ref.value}
    if ref.kind == "literal":
        return ref.value
    v = env[ref.value]
    s = t.slots[ref.value]
    if s.type in ("object", "anchor"):
        return {"slot": ref.value, "object": int(v), "phrase": idx.phrase[v]}
    if s.type == "spot":
        return {"slot": ref.value, "spot": list(v)}
    if s.type == "region":
        return {
            "slot": ref.value,
            "region": {"surface_id": v.surface_id, "kind": v.kind, "anchors": list(v.anchors), "label": v.label},
        }
    return v


def _out_json(v: Any) -> Any:
    if v.__class__ is frozenset:
        return sorted(map(int, v))
    if isinstance(v, PointValue):
        d: dict[str, Any] = {"point": [round(v.point[0], 3), round(v.point[1], 3)]}
        if v.object_id is not None:
            d["object"] = int(v.object_id)
        if v.region is not None:
            d["region"] = {
                "surface_id": v.region.surface_id,
                "kind": v.region.kind,
                "anchors": list(v.region.anchors),
                "label": v.region.label,
            }
        return d
    if isinstance(v, OptionValue):
        return {"options": [int(o) if not isinstance(o, str) else o for o in v.options], "correct": v.correct}
    if isinstance(v, NumberValue):
        return {"value": round(v.value, 6), "quantity": v.quantity}
    if isinstance(v, tuple):
        return [int(x) for x in v]
    if isinstance(v, (bool, str)):
        return v
    if isinstance(v, (int, np.integer)):
        return int(v)
    return v


def _arg_plan(t: Template, st: Step) -> tuple[tuple[str, int, Any], ...]:
    """How a record writes each argument of a step into the program record: (key, mode, payload) with mode
    0 = a constant, 1 = a step reference, 2 = an object slot, 3 = anything else (through _ref_json)."""
    out: list[tuple[str, int, Any]] = []
    for k, r in st.args.items():
        if r.kind == "all":
            out.append((k, 0, "all"))
        elif r.kind == "literal" and isinstance(r.value, (str, int, float, bool)):
            out.append((k, 0, r.value))
        elif r.kind == "step":
            out.append((k, 1, r.value))
        elif r.kind == "slot" and t.slots[r.value].type in ("object", "anchor"):
            out.append((k, 2, r.value))
        else:
            out.append((k, 3, r))
    return tuple(out)
