"""What a step op is: its arguments, output type, step count, and the hooks every stage of the engine calls.

Why one class per op (one module each, qa/ops/<name>.py): the compiler type-checks programs against
`args`/`out`, the search runs `compile` (falling back to `run`, the reference interpreter), the degeneracy
check asks `dropped`, the record and reasoning trace ask `recorded`/`key_steps`, and `verify` re-derives
the step on the raw geometry by its own code path. Adding an op is one module plus its test.
"""

from __future__ import annotations

from collections.abc import Collection
from dataclasses import dataclass
from typing import TYPE_CHECKING, Any, NamedTuple

from refspatial_gen.qa.program import Ref, Step, StepFn

if TYPE_CHECKING:
    from refspatial_gen.qa.index import SceneIndex
    from refspatial_gen.qa.keysteps import KeyWriter
    from refspatial_gen.qa.values import Context
    from refspatial_gen.qa.verify_world import Run

# Value types flowing between steps.
SET, OBJECT, POINT, BOOL, OPTION, NUMBER, MARKS = "set", "object", "point", "bool", "option", "number", "marks"
ANSWER_TYPES = (OBJECT, POINT, BOOL, OPTION, NUMBER)
SLOT_TYPES = ("object", "anchor", "relation", "direction", "surface", "number", "category", "color", "region", "spot")
FREE_KINDS = ("left_of", "right_of", "in_front_of", "behind", "between")  # free-space regions around anchors
REGION_KINDS = ("corner", "edge")  # labelled spots and regions of a support surface
TURN_AXES = {"horizontal": ("left", "right"), "vertical": ("up", "down")}


@dataclass(frozen=True)
class Arg:
    # set | object | objects | relation | direction | surface | region | spot | number | category | color |
    # bools | options | int, or a kind with `choices` (a literal word: quantity, style, axis, mode)
    kind: str
    required: bool = False
    choices: tuple[str, ...] = ()


class Recorded(NamedTuple):
    """What a step adds to a QA pair's `relations`: fixed ids, and slots whose bound value names one."""

    relations: tuple[str, ...] = ()
    region_slots: tuple[str, ...] = ()  # region slots: their kind is a relation
    spot_slots: tuple[str, ...] = ()  # spot slots: their kind (corner, edge) is a relation


class Op:
    """Defaults for an op; each op module defines a subclass and registers an instance (qa/ops/__init__.py)."""

    name = ""
    args: dict[str, Arg] = {}
    out = ""
    relation_uses: tuple[str, ...] = ()  # relation uses a `relation` argument accepts (Relation.qa)
    doc = ""
    narrowing = False  # keeps a subset of its input set (must remove at least one object)
    chain = False  # its output comes from its input set (a set step, or one object picked from it)
    needs_two = False  # picks one object of its input set: the set needs two candidates
    reads_single = False  # a step it reads by name must give exactly one object
    implicit_of = False  # without `of:` it reads the previous step's object
    locates = False  # gives the answer point of the object its input holds
    droppable = False  # the degeneracy check drops it (its removal must change the answer)
    drop_to = "input"  # a dropped step passes its input set on ("input") or gives no value ("none")
    tries = 1  # a step with random draws is run this often per binding
    targets_for = ""  # answer type whose targets this step's `target_args` name
    target_args: tuple[str, ...] = ()

    # ------------------------------------------------------------------ compile time
    def weight(self, present: Collection[str]) -> int:
        """Contribution to the question's step count, from the arguments present (formats.md: anchors +
        directional phrases). Applied to compiled steps and, by `verify`, to stored records."""
        return 0

    def check(self, args: dict[str, Ref], prior: list[Step]) -> tuple[tuple[str, ...], str] | None:
        """A shape problem the argument types do not catch: (path below the step, message), or None."""
        return None

    def needs(self, st: Step) -> dict[str, Any]:
        """What generation must find in a frame before searching (keys of program.Needs)."""
        return {}

    def recorded(self, st: Step) -> Recorded:
        return Recorded()

    # ------------------------------------------------------------------ run time
    def run(self, st: Step, env: dict[str, Any], prev: Any, ctx: Context) -> Any:
        """The reference interpreter: the step's value, or raise Reject."""
        raise NotImplementedError(self.name)

    def compile(self, st: Step) -> StepFn | None:
        """A faster equivalent of `run` returning (not raising) Reject, or None to use `run`."""
        return None

    def dropped(self, st: Step, local: dict[str, Any], prev: Any, idx: SceneIndex) -> Any:
        """The step's value when the degeneracy check removes it."""
        from refspatial_gen.qa.ops.common import set_in

        return set_in(st, local, prev, idx) if self.drop_to == "input" else None

    def replay(self, st: Step, fn: StepFn, local: dict[str, Any], prev: Any, ctx: Context, env: dict[str, Any]) -> Any:
        """The step's value when a program is re-run for the degeneracy check (`env`: the instance)."""
        from refspatial_gen.qa.index import Reject

        val = fn(local, prev, ctx)
        if val.__class__ is Reject:
            raise Reject(val.reason)  # a fresh exception: the returned one may be a shared constant
        return val

    def key_steps(self, st: Step, extra: Any, env: dict[str, Any], rel: str | None, keys: KeyWriter) -> None:
        """Op-specific key steps after the generic ones (every object argument's position); `extra` is what
        `key_extra` prepared at compile time."""

    def key_extra(self, st: Step) -> Any:
        return None

    def mark_style(self, st: Step) -> str | None:
        """How the step draws marks on the image ("box", "point"), or None when it draws none."""
        return None

    # ------------------------------------------------------------------ verify
    def verify(self, run: Run, a: dict[str, Any], prev: Any, st: dict[str, Any]) -> Any:
        """Re-derive the step from a stored record on the frame's raw geometry (qa/verify_world.py); raise
        run's Fail or Undecided when it does not hold."""
        raise NotImplementedError(self.name)

    def verify_dropped(self, a: dict[str, Any], prev: Any) -> Any:
        return frozenset(a.get("in", prev)) if self.drop_to == "input" else None
