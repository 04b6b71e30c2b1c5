"""free_space: a free point beside an anchor (2 steps), between two anchors (3) or in a corner/edge region (1)."""

from __future__ import annotations

from collections.abc import Collection
from typing import TYPE_CHECKING, Any

from refspatial_gen.qa.index import Reject
from refspatial_gen.qa.ops.base import POINT, Arg, Op, Recorded
from refspatial_gen.qa.ops.common import resolve
from refspatial_gen.qa.program import Ref, Step
from refspatial_gen.qa.values import PointValue

if TYPE_CHECKING:
    from refspatial_gen.qa.values import Context
    from refspatial_gen.qa.verify_world import Run


class FreeSpace(Op):
    name = "free_space"
    args = {"direction": Arg("direction"), "anchor": Arg("object"), "anchors": Arg("objects"), "region": Arg("region")}
    out = POINT
    doc = "a free point: direction of an anchor (2 steps), between two anchors (3), a corner/edge region (1)"

    def weight(self, present: Collection[str]) -> int:
        if "anchors" in present:
            return 3
        if "region" in present:
            return 1
        return 2

    def check(self, args: dict[str, Ref], prior: list[Step]) -> tuple[tuple[str, ...], str] | None:
        if sum(k in args for k in ("anchor", "anchors", "region")) != 1:
            return (), "free_space needs exactly one of anchor, anchors (two objects) or region"
        if "region" not in args and "anchors" not in args and "direction" not in args:
            return (), "free_space with an anchor needs a direction"
        r = args.get("anchors")
        if r is not None and len(r.value) != 2:
            return ("anchors",), "anchors must list exactly two objects"
        return None

    def needs(self, st: Step) -> dict[str, Any]:
        return {"between_region": True} if "anchors" in st.args else {}

    def recorded(self, st: Step) -> Recorded:
        region = st.args.get("region")
        return Recorded(relations=("free_space",), region_slots=(region.value,) if region is not None else ())

    def run(self, st: Step, env: dict[str, Any], prev: Any, ctx: Context) -> Any:
        idx = ctx.idx
        a = st.args
        if "region" in a:
            r = resolve(a["region"], env, prev, idx)
        elif "anchors" in a:
            b, c = resolve(a["anchors"], env, prev, idx)
            r = idx.regions.get(("between", (b, c))) or idx.regions.get(("between", (c, b)))
        else:
            d = resolve(a["direction"], env, prev, idx)
            r = idx.regions.get((d, (resolve(a["anchor"], env, prev, idx),)))
        if r is None:
            raise Reject("no_free_space")
        return PointValue((float(r.point[0]), float(r.point[1])), None, r)

    def verify(self, run: Run, a: dict[str, Any], prev: Any, st: dict[str, Any]) -> Any:
        return ("free", st.get("out", {}).get("region") or a.get("region"))  # checked by _check_answer


OP = FreeSpace()
