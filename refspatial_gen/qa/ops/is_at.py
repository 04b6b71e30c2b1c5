"""is_at: is the object at a named corner or edge of a surface (yes/no; 2 steps)."""

from __future__ import annotations

from collections.abc import Collection
from typing import TYPE_CHECKING, Any

from refspatial_gen.qa.ops.base import BOOL, Arg, Op, Recorded
from refspatial_gen.qa.ops.common import resolve
from refspatial_gen.qa.program import Step

if TYPE_CHECKING:
    from refspatial_gen.qa.values import Context
    from refspatial_gen.qa.verify_world import Run


class IsAt(Op):
    name = "is_at"
    args = {"a": Arg("object", True), "spot": Arg("spot", True)}
    out = BOOL
    doc = "is the object at a named corner or edge of a surface (2 steps)"
    droppable = True
    drop_to = "none"
    targets_for, target_args = BOOL, ("a", "b")

    def weight(self, present: Collection[str]) -> int:
        return 2

    def recorded(self, st: Step) -> Recorded:
        return Recorded(spot_slots=(st.args["spot"].value,))

    def run(self, st: Step, env: dict[str, Any], prev: Any, ctx: Context) -> Any:
        idx = ctx.idx
        kind, sid, label = resolve(st.args["spot"], env, prev, idx)
        return idx.holds(kind, (resolve(st.args["a"], env, prev, idx), sid, label))

    def verify(self, run: Run, a: dict[str, Any], prev: Any, st: dict[str, Any]) -> Any:
        kind, sid, label = a["spot"]
        return run.w.holds(kind, a["a"], sid, label)


OP = IsAt()
