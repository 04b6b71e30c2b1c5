"""locate: the answer point of one object (0 steps)."""

from __future__ import annotations

from typing import TYPE_CHECKING, Any

from refspatial_gen.qa.ops.base import OBJECT, POINT, SET, Arg, Op
from refspatial_gen.qa.ops.common import EMPTY, NO_POINT, NOT_UNIQUE, name_of, resolve, single
from refspatial_gen.qa.program import Ref, Step, StepFn
from refspatial_gen.qa.values import PointValue

if TYPE_CHECKING:
    from refspatial_gen.qa.values import Context
    from refspatial_gen.qa.verify_world import Run


class Locate(Op):
    name = "locate"
    args = {"of": Arg("object")}
    out = POINT
    doc = "the answer point of one object (0 steps)"
    reads_single = implicit_of = locates = True

    def check(self, args: dict[str, Ref], prior: list[Step]) -> tuple[tuple[str, ...], str] | None:
        if "of" not in args and not (prior and prior[-1].out in (SET, OBJECT)):
            return (), "locate needs of: (an object) or a preceding step that selects objects"
        return None

    def run(self, st: Step, env: dict[str, Any], prev: Any, ctx: Context) -> Any:
        idx = ctx.idx
        obj = single(resolve(st.args.get("of"), env, prev, idx))
        return PointValue(idx.point(obj), obj)

    def compile(self, st: Step) -> StepFn | None:
        ref = st.args.get("of")
        of = name_of(ref)
        if ref is not None and of is None:
            return None

        def fn(env: dict[str, Any], prev: Any, ctx: Any) -> Any:
            v = prev if of is None else env[of]
            if v.__class__ is frozenset:
                if len(v) != 1:
                    return NOT_UNIQUE if v else EMPTY
                v = next(iter(v))
            p = ctx.idx.nodes[v].point
            if p is None:
                return NO_POINT
            return PointValue((float(p[0]), float(p[1])), v)

        return fn

    def verify(self, run: Run, a: dict[str, Any], prev: Any, st: dict[str, Any]) -> Any:
        return ("object", run.one(a.get("of", prev)))


OP = Locate()
