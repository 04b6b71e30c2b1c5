"""mark: draw labelled boxes or points around `count` objects on a copy of the image (0 steps)."""

from __future__ import annotations

from typing import TYPE_CHECKING, Any

from refspatial_gen.qa.index import Reject
from refspatial_gen.qa.ops.base import MARKS, Arg, Op
from refspatial_gen.qa.ops.common import resolve, set_in
from refspatial_gen.qa.program import Step, StepFn

if TYPE_CHECKING:
    from refspatial_gen.qa.values import Context
    from refspatial_gen.qa.verify_world import Run


def style_of(st: Step) -> str:
    return st.args["style"].value if "style" in st.args else "box"


class Mark(Op):
    name = "mark"
    args = {"in": Arg("set"), "count": Arg("int"), "style": Arg("style", choices=("box", "point"))}
    out = MARKS
    doc = "draw labelled boxes or points on a copy of the image around `count` objects (0 steps)"
    tries = 3  # a random draw: another draw of the same binding may pass

    def run(self, st: Step, env: dict[str, Any], prev: Any, ctx: Context) -> Any:
        idx = ctx.idx
        s = sorted(i for i in set_in(st, env, prev, idx) if i in idx.referable)
        n = resolve(st.args.get("count"), env, prev, idx) or 3
        if len(s) < n:
            raise Reject("too_few")
        pick = ctx.rng.choice(len(s), size=n, replace=False)
        return tuple(s[int(k)] for k in pick)

    def mark_style(self, st: Step) -> str | None:
        return style_of(st)

    def replay(self, st: Step, fn: StepFn, local: dict[str, Any], prev: Any, ctx: Context, env: dict[str, Any]) -> Any:
        return env[st.name]  # the drawn marks are part of the question

    def verify(self, run: Run, a: dict[str, Any], prev: Any, st: dict[str, Any]) -> Any:
        marks = [int(m) for m in st.get("out") or []]
        w = run.w
        for m in marks:
            if m not in w.objects or w.objects[m].mask is None:
                raise run.fail(f"marked object {m} is not a visible object of the frame")
        return marks


OP = Mark()
