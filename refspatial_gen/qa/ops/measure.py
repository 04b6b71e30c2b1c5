"""measure: a metric quantity of one or two objects (steps: objects involved - 1)."""

from __future__ import annotations

from collections.abc import Collection
from typing import TYPE_CHECKING, Any

from refspatial_gen.qa.index import Reject
from refspatial_gen.qa.ops.base import NUMBER, OBJECT, SET, Arg, Op, Recorded
from refspatial_gen.qa.ops.common import resolve, single
from refspatial_gen.qa.program import Ref, Step
from refspatial_gen.qa.values import NumberValue

if TYPE_CHECKING:
    from refspatial_gen.qa.keysteps import KeyWriter
    from refspatial_gen.qa.values import Context
    from refspatial_gen.qa.verify_world import Run

QUANTITIES = {  # quantity -> (number of objects, relation id recorded, unit kind)
    "distance": (2, "distance", "length"),
    "depth": (1, "depth", "length"),
    "height": (1, "tall", "length"),
    "width": (1, "wide", "length"),
    "angle": (2, "angle", "angle"),
    "rotation_horizontal": (1, "rotation_horizontal", "turn"),
    "rotation_vertical": (1, "rotation_vertical", "turn"),
}


class Measure(Op):
    name = "measure"
    args = {"quantity": Arg("quantity", True, tuple(QUANTITIES)), "of": Arg("object"), "to": Arg("object")}
    out = NUMBER
    doc = "a metric quantity (steps: objects involved - 1)"
    reads_single = implicit_of = True
    targets_for, target_args = NUMBER, ("of", "to")

    def weight(self, present: Collection[str]) -> int:
        return 1 if "to" in present else 0

    def check(self, args: dict[str, Ref], prior: list[Step]) -> tuple[tuple[str, ...], str] | None:
        q = args["quantity"].value
        n = QUANTITIES[q][0]
        if "of" not in args and not (prior and prior[-1].out in (OBJECT, SET)):
            return (), "measure needs of: (an object)"
        if n == 2 and "to" not in args:
            return (), f"measure {q} needs to: (a second object)"
        if n == 1 and "to" in args:
            return ("to",), f"measure {q} takes one object"
        return None

    def recorded(self, st: Step) -> Recorded:
        return Recorded(relations=(QUANTITIES[st.args["quantity"].value][1],))

    def run(self, st: Step, env: dict[str, Any], prev: Any, ctx: Context) -> Any:
        idx = ctx.idx
        a = st.args
        q = a["quantity"].value
        x = single(resolve(a.get("of"), env, prev, idx))
        if q == "distance" or q == "angle":
            y = resolve(a["to"], env, prev, idx)
            if x == y:
                raise Reject("same_object")
            if q == "angle" and not (idx.has_front.get(x) and idx.has_front.get(y)):
                raise Reject("no_front")
            idx.holds(q, (x, y))  # an undecided quantity (unknown front...) is not asked
            return NumberValue(idx.value(q, (x, y)), q)
        if q == "depth" or q.startswith("rotation"):
            idx.holds(q, (x,))  # depth of an object spanning a long range, a turn inside the margin
            return NumberValue(idx.value(q, (x,)), q)
        w, _, h = idx.size(x)
        return NumberValue(h if q == "height" else w, q)

    def key_extra(self, st: Step) -> Any:
        a = st.args
        return a["quantity"].value, tuple(a[k].value for k in ("of", "to") if k in a), "of" not in a

    def key_steps(self, st: Step, extra: Any, env: dict[str, Any], rel: str | None, keys: KeyWriter) -> None:
        q, names, from_prev = extra
        targets = [keys.one(env[nm]) for nm in names]
        if from_prev:
            prev = env[keys.steps[st.index - 1].name]
            targets.insert(0, next(iter(prev)) if isinstance(prev, frozenset) else prev)
        for o in targets:
            if q in ("height", "width"):
                keys.size(o, q)
            elif q == "angle":
                keys.orient(o)
            else:
                keys.pos(o)

    def verify(self, run: Run, a: dict[str, Any], prev: Any, st: dict[str, Any]) -> Any:
        x = a.get("of", prev)
        if isinstance(x, (frozenset, set, list)):
            if len(x) != 1:
                raise run.fail(f"measured object is not unique: {sorted(x)}")
            x = next(iter(x))
        return ("number", a["quantity"], run.quantity(a["quantity"], int(x), a.get("to")))


OP = Measure()
