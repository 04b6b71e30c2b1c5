"""all: the logical and of earlier yes/no steps (0 steps)."""

from __future__ import annotations

from typing import TYPE_CHECKING, Any

from refspatial_gen.qa.index import Reject
from refspatial_gen.qa.ops.base import BOOL, Arg, Op
from refspatial_gen.qa.ops.common import resolve
from refspatial_gen.qa.program import Step, StepFn

if TYPE_CHECKING:
    from refspatial_gen.qa.values import Context
    from refspatial_gen.qa.verify_world import Run


class All(Op):
    name = "all"
    args = {"of": Arg("bools", True)}
    out = BOOL
    doc = "logical and of earlier yes/no steps (0 steps)"

    def run(self, st: Step, env: dict[str, Any], prev: Any, ctx: Context) -> Any:
        return all(resolve(st.args["of"], env, prev, ctx.idx))

    def replay(self, st: Step, fn: StepFn, local: dict[str, Any], prev: Any, ctx: Context, env: dict[str, Any]) -> Any:
        """A dropped yes/no step (None) leaves the others to decide; none left: no answer."""
        vals = [local[r.value] for r in st.args["of"].value]
        vals = [v for v in vals if v is not None]
        if not vals:
            raise Reject("empty")
        return all(vals)

    def verify(self, run: Run, a: dict[str, Any], prev: Any, st: dict[str, Any]) -> Any:
        vals = [v for v in a["of"] if v is not None]
        if not vals:
            raise run.fail("all: nothing left")
        return all(vals)


OP = All()
