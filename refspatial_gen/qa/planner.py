"""plan_program: every plan the engine derives from a compiled template, made once by the compiler.

Why here and not in the stages that use them: a plan computed lazily inside a template object is state
nobody owns; computed once at compile time, each plan is a plain value of the template's Program
(qa/program.py), and every stage reads the same one.
"""

from __future__ import annotations

from refspatial_gen.qa.executor import answer_chain, compile_step
from refspatial_gen.qa.keysteps import plan_keys
from refspatial_gen.qa.program import Needs, Program, SearchRow, Template
from refspatial_gen.qa.record import plan_record


def plan_program(t: Template) -> Program:
    fns = tuple(compile_step(st) for st in t.steps)
    chain = answer_chain(t.steps)
    objslots = {n for n, s in t.slots.items() if s.type in ("object", "anchor")}
    search = tuple(
        SearchRow(
            st, st.binds, tuple(k for k, nm in enumerate(st.binds) if nm in objslots), st.impl.tries, fn, on_chain
        )
        for st, fn, on_chain in zip(t.steps, fns, chain)
    )
    wants = [st.impl.needs(st) for st in t.steps]
    needs = Needs(
        any(w.get("multiview") for w in wants),
        any(w.get("spot") for w in wants),
        max([w["between"] for w in wants if "between" in w] or [0]),
        any(w.get("between_region") for w in wants),
        tuple(sorted(t.slots)),
    )
    t.program = Program(fns, search, chain, needs, None, (), {n: s.signature() for n, s in t.slots.items()})
    t.program.record = plan_record(t)  # reads the targets and mark style the program already knows
    t.program.keys = plan_keys(t)
    return t.program
