"""Template compilation, part two: the `program:` steps, each argument typed against its op's declaration
(qa/ops/), references to slots and earlier steps checked, then binding order and pruning bounds."""

from __future__ import annotations

from typing import Any

from refspatial_gen.qa.ops import OPS, allowed_relations
from refspatial_gen.qa.ops.base import BOOL, FREE_KINDS, MARKS, OBJECT, SET, Arg, Op
from refspatial_gen.qa.program import Ref, SlotSpec, Step
from refspatial_gen.qa.slots import Ctx, Path
from refspatial_gen.yamlpos import line_of

RelUses = dict[str, tuple[set[str], tuple[str, ...]]]  # relation slot -> (relations every use allows, first order)


def flat_refs(args: dict[str, Ref]) -> list[Ref]:
    out = []
    for r in args.values():
        if r.kind == "list":
            out.extend(r.value)
        else:
            out.append(r)
    return out


def compile_program(v: Any, path: Path, ctx: Ctx, slots: dict[str, SlotSpec], known_rel: tuple[str, ...]) -> list[Step]:
    if not isinstance(v, list) or not v:
        ctx.err(path, "program must be a non-empty list of steps")
        return []
    steps: list[Step] = []
    names: dict[str, Step] = {}
    rel_uses: RelUses = {}
    for i, raw in enumerate(v):
        st = _compile_step(raw, i, path + (i,), ctx, slots, names, known_rel, rel_uses, steps)
        if st is None:
            return []
        steps.append(st)
        names[st.name] = st
    for sname, (allowed, order) in rel_uses.items():
        s = slots[sname]
        if s.choices is None:  # in the op's order (a set's order would depend on the process's hash seed)
            s.choices = tuple(r for r in order if r in allowed and r in known_rel)
        else:
            for r in s.choices:
                if r not in allowed and r in known_rel:
                    ctx.err(path, f"relation {r!r} (slot {sname!r}) cannot be used by every step that uses the slot")
    return steps


def _compile_step(
    raw: Any,
    i: int,
    p: Path,
    ctx: Ctx,
    slots: dict[str, SlotSpec],
    names: dict[str, Step],
    known_rel: tuple[str, ...],
    rel_uses: RelUses,
    prior: list[Step],
) -> Step | None:
    if not isinstance(raw, dict):
        ctx.err(p, f"a step must be a mapping with 'op:', got {type(raw).__name__}")
        return None
    op = raw.get("op")
    if not isinstance(op, str) or op not in OPS:
        ctx.err(p + ("op",), f"unknown op {op!r} (known: {', '.join(sorted(OPS.names()))})")
        return None
    spec = OPS[op]
    sname = raw.get("as", f"step{i + 1}")
    if not isinstance(sname, str) or not sname.isidentifier() or sname in slots or sname in names:
        ctx.err(p + ("as",), f"step name {sname!r} must be a new identifier (not a slot or earlier step)")
        return None
    args: dict[str, Ref] = {}
    ok = True
    for k in raw:
        if k not in ("op", "as") and k not in spec.args:
            ctx.err(p + (k,), f"op {op!r} has no argument {k!r} (arguments: {', '.join(spec.args)})")
            ok = False
    for k, a in spec.args.items():
        if k not in raw or raw[k] is None:
            if a.required:
                ctx.err(p, f"op {op!r} needs argument {k!r}")
                ok = False
            continue
        r = _ArgReader(spec, p + (k,), ctx, slots, names, known_rel, rel_uses).read(raw[k], a)
        if r is None:
            ok = False
        else:
            args[k] = r
    if not ok:
        return None
    problem = spec.check(args, prior)
    if problem is not None:
        ctx.err(p + problem[0], problem[1])
        return None
    return Step(i, op, sname, args, spec.out, line_of(ctx.lines, p), spec.weight(args.keys()), impl=spec)


class _ArgReader:
    """Reads one argument of one step into a Ref, by the kind its op declares."""

    def __init__(
        self,
        spec: Op,
        p: Path,
        ctx: Ctx,
        slots: dict[str, SlotSpec],
        names: dict[str, Step],
        known_rel: tuple[str, ...],
        rel_uses: RelUses,
    ) -> None:
        self.spec, self.p, self.ctx, self.slots, self.names = spec, p, ctx, slots, names
        self.known_rel, self.rel_uses = known_rel, rel_uses

    def err(self, msg: str) -> None:
        self.ctx.err(self.p, msg)

    def read(self, v: Any, arg: Arg) -> Ref | None:
        kind, spec, p = arg.kind, self.spec, self.p
        if kind == "set":
            return Ref("all") if v == "all" else self.slot_or_step(v, (), (SET,), "a set of objects")
        if kind == "object":  # a step giving a set is accepted: it must hold exactly one object at run time
            return self.slot_or_step(v, ("object", "anchor"), (OBJECT, SET), "an object")
        if kind == "objects" or kind == "options":
            if kind == "options" and isinstance(v, str) and v in self.names and self.names[v].out == MARKS:
                return Ref("step", v)
            if not isinstance(v, list):
                self.err(f"{spec.name}.{p[-1]} must be a list of objects")
                return None
            return self.refs(v, ("object", "anchor"), (OBJECT,), "an object")
        if kind == "relation":
            return self.relation(v)
        if kind in ("direction", "surface", "region", "spot", "number", "category", "color"):
            return self.named(v, kind)
        if kind == "bools":
            if not isinstance(v, list) or len(v) < 2:
                self.err("all.of must list at least two earlier yes/no steps")
                return None
            return self.refs(v, (), (BOOL,), "a yes/no step")
        if arg.choices:
            if v not in arg.choices:
                self.err(f"{spec.name}.{p[-1]} must be one of {', '.join(arg.choices)}, got {v!r}")
                return None
            return Ref("literal", v)
        if kind == "int":
            if isinstance(v, bool) or not isinstance(v, int) or not 2 <= v <= 6:
                self.err(f"{spec.name}.{p[-1]} must be an integer from 2 to 6, got {v!r}")
                return None
            return Ref("literal", v)
        self.err(f"cannot read argument {p[-1]!r}")
        return None

    def slot_or_step(self, x: Any, want_slot: tuple[str, ...], want_step: tuple[str, ...], what: str) -> Ref | None:
        slots, names, where = self.slots, self.names, f"{self.spec.name}.{self.p[-1]}"
        if not isinstance(x, str):
            self.err(f"{what} must be a slot or step name, got {type(x).__name__} {x!r}")
            return None
        if x in slots:
            if slots[x].type not in want_slot:
                self.err(f"{x!r} is a {slots[x].type} slot; {where} needs {what}")
                return None
            return Ref("slot", x)
        if x in names:
            if names[x].out not in want_step:
                self.err(f"step {x!r} gives a {names[x].out}; {where} needs {what}")
                return None
            return Ref("step", x)
        self.err(
            f"unknown slot {x!r} (slots: {', '.join(sorted(slots)) or 'none'}; steps: {', '.join(names) or 'none'})"
        )
        return None

    def refs(self, v: list[Any], want_slot: tuple[str, ...], want_step: tuple[str, ...], what: str) -> Ref | None:
        out = []
        for x in v:
            r = self.slot_or_step(x, want_slot, want_step, what)
            if r is None:
                return None
            out.append(r)
        return Ref("list", tuple(out))

    def relation(self, v: Any) -> Ref | None:
        spec, slots = self.spec, self.slots
        if isinstance(v, str) and v in slots:
            if slots[v].type != "relation":
                self.err(f"{v!r} is a {slots[v].type} slot; {spec.name}.relation needs a relation")
                return None
            order = allowed_relations(spec)
            seen, first = self.rel_uses.get(v, (set(order), order))
            self.rel_uses[v] = (seen & set(order), first)
            return Ref("slot", v)
        if not isinstance(v, str) or v not in self.known_rel:
            self.err(f"unknown relation {v!r} (known: {', '.join(self.known_rel)})")
            return None
        allowed = allowed_relations(spec)
        if v not in allowed:
            self.err(f"relation {v!r} cannot be used with {spec.name} (allowed: {', '.join(allowed)})")
            return None
        return Ref("literal", v)

    def named(self, v: Any, kind: str) -> Ref | None:
        """A slot of the kind, or a literal where the kind has them (directions, numbers, names)."""
        where = f"{self.spec.name}.{self.p[-1]}"
        if isinstance(v, str) and v in self.slots:
            if self.slots[v].type != kind:
                self.err(f"{v!r} is a {self.slots[v].type} slot; {where} needs a {kind}")
                return None
            return Ref("slot", v)
        if kind == "direction" and isinstance(v, str) and v in FREE_KINDS:
            return Ref("literal", v)
        if kind == "number" and isinstance(v, int) and not isinstance(v, bool) and 1 <= v <= 8:
            return Ref("literal", v)
        if kind in ("surface", "category", "color") and isinstance(v, str) and v:
            return Ref("literal", v)
        self.err(
            f"unknown slot {v!r}: {where} needs a {kind} slot"
            + (" or literal" if kind not in ("region", "spot") else "")
        )
        return None


def assign_binds(steps: list[Step], slots: dict[str, SlotSpec]) -> None:
    seen: set[str] = set()
    for st in steps:
        b = []
        for r in flat_refs(st.args):
            if r.kind == "slot" and r.value not in seen:
                seen.add(r.value)
                b.append(r.value)
        st.binds = tuple(b)


def assign_bounds(steps: list[Step]) -> None:
    """Early pruning bounds: every later narrowing step must remove at least one object (else it is
    degenerate), a step picking one object of its input needs two candidates, and the set a single-object
    consumer reads must hold exactly one object."""
    for i, st in enumerate(steps):
        if st.out != SET:
            continue
        need = 1
        j = i + 1
        while j < len(steps) and steps[j].args.get("in") is None and steps[j].impl.narrowing:
            need += 1
            j += 1
        nxt = steps[j] if j < len(steps) else None
        if nxt is not None and nxt.impl.needs_two and nxt.args.get("in") is None:
            need += 1
        st.min_out = need
        if j == i + 1 and nxt is not None and nxt.impl.implicit_of and nxt.args.get("of") is None:
            st.exact_one = True
        for later in steps[i + 1 :]:
            for r in later.args.values():
                rs = r.value if r.kind == "list" else (r,)
                for x in rs:
                    if isinstance(x, Ref) and x.kind == "step" and x.value == st.name and later.impl.reads_single:
                        st.exact_one = True
