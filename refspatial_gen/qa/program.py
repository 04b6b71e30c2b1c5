"""What the template compiler produces: slots, typed steps, and one Program holding every derived plan.

Why one object: the search, the degeneracy check, the record and key-step rendering each need facts about a
template that do not depend on the scene (compiled step functions, binding order, bounds, which relations a
question names...). The compiler derives them all once (qa/planner.py), so nothing is computed lazily on
the hot path and a template's plans cannot drift from its steps.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass, field
from typing import TYPE_CHECKING, Any, NamedTuple

if TYPE_CHECKING:
    from refspatial_gen.qa.ops.base import Op
    from refspatial_gen.qa.text import Seq

StepFn = Callable[[dict[str, Any], Any, Any], Any]  # (env, prev, ctx) -> value, or a Reject (returned, not raised)


@dataclass(frozen=True)
class Ref:
    """An argument: a slot, an earlier step's output, a literal, or the previous step (`None` value)."""

    kind: str  # "slot" | "step" | "literal" | "prev" | "all" | "list"
    value: Any = None


@dataclass
class SlotSpec:
    name: str
    type: str
    line: int | None
    choices: tuple[Any, ...] | None = None
    category: tuple[str, ...] | None = None
    has_front: bool | None = None
    min: int = 1
    max: int = 3
    kinds: tuple[str, ...] | None = None
    phrases: dict[str, dict[str, Seq]] = field(default_factory=dict)

    def signature(self) -> tuple[Any, ...]:
        """What the slot's candidates in a frame depend on (frames memoise candidate lists under it)."""
        return (self.type, self.choices, self.category, self.has_front, self.min, self.max, self.kinds)


@dataclass
class Step:
    index: int
    op: str
    name: str
    args: dict[str, Ref]
    out: str
    line: int | None
    weight: int
    binds: tuple[str, ...] = ()  # slots first needed at this step (bound by the search just before it runs)
    min_out: int = 1  # a set this step gives must hold at least this many objects (later steps narrow it)
    exact_one: bool = False  # the set this step gives is the described object: exactly one
    impl: Op = field(default=None, compare=False, repr=False)  # type: ignore[assignment]  # the op (qa/ops/)


class Needs(NamedTuple):
    """What generation asks of a template on every attempt, read from its steps once."""

    multiview: bool  # a step needs a second view
    spot: bool  # a step keeps objects at a corner or edge: some object must be at one
    between: int  # the most objects any `between` step must keep (its search bound; 0 = no such step)
    between_region: bool  # free space between two anchors: the graph must have such a region
    slot_names: tuple[str, ...]  # sorted: the dedup key reads the instance's slots in this order


class SearchRow(NamedTuple):
    """One step as the search runs it."""

    step: Step
    binds: tuple[str, ...]  # slots bound just before the step
    objects: tuple[int, ...]  # positions in `binds` of object slots (must bind distinct objects)
    tries: int  # how often the step is run per binding (steps with random draws)
    fn: StepFn  # the compiled step
    on_chain: bool  # the answer object is certainly a member of this step's output set


@dataclass
class Program:
    """Every plan derived from one template's steps (built by qa/planner.plan_program at compile time)."""

    fns: tuple[StepFn, ...]
    search: tuple[SearchRow, ...]
    answer_chain: tuple[bool, ...]
    needs: Needs
    record: Any  # qa/record.RecordPlan
    keys: tuple[Any, ...]  # qa/keysteps.KeyPlan per step
    signatures: dict[str, tuple[Any, ...]]  # slot name -> SlotSpec.signature()


@dataclass
class Template:
    name: str
    file: str
    line: int | None
    weight: float
    slots: dict[str, SlotSpec]
    steps: list[Step]
    texts: list[Seq]
    instructions: list[Seq] | None
    n_steps: int
    answer_type: str
    relations: tuple[str, ...]  # literal relation ids (slot relations are added per instance)
    family: str = ""
    unbound: tuple[str, ...] = ()  # slots only used in text (bound before rendering)
    answer_form: str = "letter"  # choice answers: "letter" -> "(B)", "letter_option" -> "(B) no" (one per template)
    program: Program = field(default=None, compare=False, repr=False)  # type: ignore[assignment]
