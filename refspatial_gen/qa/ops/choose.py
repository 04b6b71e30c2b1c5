"""choose: among options, the one that wins (mode most) or the only one that satisfies (mode which);
1 step, 3 with an anchor. Options are objects, or the marks a `mark` step drew."""

from __future__ import annotations

from collections.abc import Collection
from typing import TYPE_CHECKING, Any

from refspatial_gen.graph.relations import REGISTRY
from refspatial_gen.qa.index import Reject
from refspatial_gen.qa.ops.base import OPTION, Arg, Op
from refspatial_gen.qa.ops.common import anchored, resolve, winner
from refspatial_gen.qa.ops.superlative import needs_anchor
from refspatial_gen.qa.program import Ref, Step
from refspatial_gen.qa.values import OptionValue

if TYPE_CHECKING:
    from refspatial_gen.qa.keysteps import KeyWriter
    from refspatial_gen.qa.values import Context
    from refspatial_gen.qa.verify_world import Run


class Choose(Op):
    name = "choose"
    args = {
        "options": Arg("options", True),
        "relation": Arg("relation", True),
        "anchor": Arg("object"),
        "mode": Arg("mode", choices=("most", "which")),
    }
    out = OPTION
    relation_uses = ("ordered", "pairwise", "anchored")
    doc = "pick the option that wins (mode most) or the only one that satisfies (mode which); 1 step + 2 with anchor"
    reads_single = True

    def weight(self, present: Collection[str]) -> int:
        return 3 if "anchor" in present else 1

    def check(self, args: dict[str, Ref], prior: list[Step]) -> tuple[tuple[str, ...], str] | None:
        r = args["options"]
        if r.kind == "list" and len(r.value) < 2:
            return ("options",), "choose needs at least two options"
        return needs_anchor(args)

    def run(self, st: Step, env: dict[str, Any], prev: Any, ctx: Context) -> Any:
        idx = ctx.idx
        a = st.args
        opts = resolve(a["options"], env, prev, idx)
        rel = resolve(a["relation"], env, prev, idx)
        anchor = resolve(a["anchor"], env, prev, idx) if "anchor" in a else None
        if len(set(opts)) != len(opts) or (anchor is not None and anchor in opts):
            raise Reject("same_object")
        mode = a["mode"].value if "mode" in a else "most"
        if mode == "which" and not anchored(rel):
            if anchor is None:
                raise Reject("no_anchor")
            sat = [i for i, o in enumerate(opts) if idx.holds(rel, (o, anchor))]
            if len(sat) != 1:
                raise Reject("not_unique" if sat else "empty")
            win = sat[0]
        else:
            if anchored(rel) and anchor is None:
                raise Reject("no_anchor")
            if REGISTRY[rel].qa == "pairwise":
                raise Reject("not_ordered")
            win = list(opts).index(winner(opts, rel, anchor, idx))
        return OptionValue(tuple(opts), win, marks="options" in a and a["options"].kind == "step")

    def key_extra(self, st: Step) -> Any:
        opts = st.args["options"]
        return opts.value if opts.kind == "step" else None  # the mark step whose marks are the options

    def key_steps(self, st: Step, extra: Any, env: dict[str, Any], rel: str | None, keys: KeyWriter) -> None:
        if extra is None:
            return
        measure = keys.size_measure(rel) if rel is not None and REGISTRY[rel].key_step == "Size" else ""
        for i, o in enumerate(env[extra]):
            keys.pos(o, f"the object marked ({keys.letters[i]})")
            if measure:
                keys.size(o, measure)

    def verify(self, run: Run, a: dict[str, Any], prev: Any, st: dict[str, Any]) -> Any:
        opts = list(a["options"])
        rel, anchor = a["relation"], a.get("anchor")
        if a.get("mode") == "which" and not run.anchored(rel):
            sat = [o for o in opts if run.w.holds(rel, o, anchor)]
            if len(sat) != 1:
                raise run.fail(f"choose which: {len(sat)} options satisfy {rel}")
            return ("option", sat[0])
        return ("option", run.most(opts, rel, anchor))


OP = Choose()
