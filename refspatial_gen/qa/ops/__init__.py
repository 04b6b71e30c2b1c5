"""The step ops a template program is made of, one module each, registered by name.

Why one registry: the compiler type-checks programs against each op's declared arguments (a bad template
fails at load with file:line), the step count of a template is known before any scene is seen (formats.md
rule), and the search, the record, the key steps and `verify` all ask the same op object. Adding an op:
one module defining an `Op` subclass (qa/ops/base.py) registered here (or with `OPS.add` from elsewhere),
plus its test. docs/architecture.md walks through an example.
"""

from __future__ import annotations

from refspatial_gen.core.registry import Registry
from refspatial_gen.graph.relations import ids_by_use
from refspatial_gen.qa.ops.base import (
    ANSWER_TYPES,
    BOOL,
    FREE_KINDS,
    MARKS,
    NUMBER,
    OBJECT,
    OPTION,
    POINT,
    REGION_KINDS,
    SET,
    SLOT_TYPES,
    TURN_AXES,
    Arg,
    Op,
    Recorded,
)

OPS: Registry[Op] = Registry("op")
for _name, _module in (
    ("filter", "filter"),
    ("relate", "relate"),
    ("between", "between"),
    ("superlative", "superlative"),
    ("ordinal", "ordinal"),
    ("at", "at"),
    ("is_at", "is_at"),
    ("locate", "locate"),
    ("free_space", "free_space"),
    ("compare", "compare"),
    ("all", "all_of"),
    ("measure", "measure"),
    ("mark", "mark"),
    ("choose", "choose"),
    ("camera_turn", "camera_turn"),
):
    OPS.add(_name, f"refspatial_gen.qa.ops.{_module}:OP")


def allowed_relations(op: Op) -> tuple[str, ...]:
    """The relation ids an op's `relation` argument accepts, from the relation registry (Relation.qa)."""
    return tuple(r for use in op.relation_uses for r in ids_by_use(use))


__all__ = [
    "ANSWER_TYPES",
    "BOOL",
    "FREE_KINDS",
    "MARKS",
    "NUMBER",
    "OBJECT",
    "OPS",
    "OPTION",
    "POINT",
    "REGION_KINDS",
    "SET",
    "SLOT_TYPES",
    "TURN_AXES",
    "Arg",
    "Op",
    "Recorded",
    "allowed_relations",
]
