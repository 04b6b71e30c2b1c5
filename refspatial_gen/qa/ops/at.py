"""at: keep the objects at a named corner or edge of a surface (surface + phrase: 2 steps)."""

from __future__ import annotations

from collections.abc import Collection
from typing import TYPE_CHECKING, Any

from refspatial_gen.qa.ops.base import SET, Arg, Op, Recorded
from refspatial_gen.qa.ops.common import bounded, resolve, set_in
from refspatial_gen.qa.program import Step

if TYPE_CHECKING:
    from refspatial_gen.qa.values import Context
    from refspatial_gen.qa.verify_world import Run


class At(Op):
    name = "at"
    args = {"in": Arg("set"), "spot": Arg("spot", True)}
    out = SET
    doc = "keep objects at a named corner or edge of a surface (surface + phrase: 2 steps)"
    narrowing = chain = droppable = True

    def weight(self, present: Collection[str]) -> int:
        return 2

    def needs(self, st: Step) -> dict[str, Any]:
        return {"spot": True}

    def recorded(self, st: Step) -> Recorded:
        return Recorded(spot_slots=(st.args["spot"].value,))

    def run(self, st: Step, env: dict[str, Any], prev: Any, ctx: Context) -> Any:
        idx = ctx.idx
        s = set_in(st, env, prev, idx)
        kind, sid, label = resolve(st.args["spot"], env, prev, idx)
        return bounded(st, s, frozenset(x for x in s if idx.holds(kind, (x, sid, label))), ctx)

    def verify(self, run: Run, a: dict[str, Any], prev: Any, st: dict[str, Any]) -> Any:
        kind, sid, label = a["spot"]
        return frozenset(x for x in run.input_set(a) if run.w.holds(kind, x, sid, label))


OP = At()
