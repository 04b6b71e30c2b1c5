"""A relation is one registered object: what it means, how it evaluates on a frame's geometry, which of its
instances a stored graph keeps, and how a stored graph answers a single instance or the whole table.

Why one object: the graph builder, the lookup tables (graph/tables.py), the QA engine, the verifier,
`refspatial-gen relations` and the tests all read the same registration, so adding a relation is one
module (a `register(Relation(...))` call), its thresholds, a wording line (qa/lexicon.py) and a test.

Storage kinds (keep stored graphs compact):
- "pair": antisymmetric comparison; one fact per unordered pair, stored as (lower id, higher);
  R(b, a) is the negation of R(a, b) with the value negated. Mirrors (right of left) swap arguments.
- "symmetric": one fact per unordered pair; R(a, b) == R(b, a).
- "unary": one fact per object (quantities such as depth or rotation angles).
- "sparse": only holding (True) and undecided (None) instances are stored; an absent instance follows the
  relation's `cell` rule (usually False inside its domain).
- "derived": not stored; computed by `cell` from stored node attributes and facts (close/far, sizes...).
- "region": answered by free-space regions (free_space).
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass, field
from typing import TYPE_CHECKING, Any, NamedTuple

from refspatial_gen.core.model import RelationFact
from refspatial_gen.core.registry import Registry

if TYPE_CHECKING:
    from refspatial_gen.graph.scene import SceneGeom
    from refspatial_gen.graph.tables import RelationTables

ALL_SOURCES = ("sim", "toy", "scan", "image")
FRONT_SOURCES = ("sim", "toy", "scan*", "image*")  # * = only when the annotation gives a front direction
SURFACE_SOURCES = ("sim", "toy", "scan")

# codes of whole-relation tables (graph/tables.py): rows[i][j] is R(ids[i], ids[j])
T_FALSE, T_TRUE, T_UNDECIDED, T_MISSING = 0, 1, 2, 3
HOLDS_OF_CODE: tuple[bool | None, ...] = (False, True, None, None)  # table code -> holds (missing reads None)

Rows = list[list[int]]


class Cell(NamedTuple):
    """One instance looked up in a stored graph: the decision (None = undecided), value and margin (a
    NamedTuple, not a RelationFact: the QA engine builds hundreds per sample)."""

    holds: bool | None
    value: float
    margin: float


CellRule = Callable[["RelationTables", tuple[Any, ...]], Cell | None]
TableRule = Callable[["RelationTables"], Any]


@dataclass(frozen=True)
class Relation:
    id: str
    group: str
    frame: str  # "cam" | "img" | "world" | "obj"
    arity: int
    value: str  # the metric quantity the decision rests on, with its unit
    margin: str  # names of the Thresholds fields that set the undecided band
    definition: str
    sources: tuple[str, ...] = ALL_SOURCES
    storage: str = "pair"
    mirror_of: str | None = None  # this relation is `mirror_of` with the first two arguments swapped
    negation_of: str | None = None  # this relation is the negation of `negation_of` (same arguments)
    needs: tuple[str, ...] = ()  # "gravity", "front", "surface"
    spec: bool = True  # one of the 31 of shared/spec/relations.md
    # how templates may use it: "ordered" (orders two objects: relate, compare, superlative, ordinal, choose),
    # "pairwise" (a property of a pair: relate, compare, choose), "anchored" (A closer to C than B: needs an
    # anchor), "" (asked only through its own op or quantity, or not at all)
    qa: str = ""
    key_step: str = ""  # what a reasoning trace must perceive of the objects: "Size" | "Orientation" | ""
    variadic: bool = False  # takes a variable number of arguments (free_space: surface, kind, anchors...)
    world_only: bool | None = None  # not evaluated without gravity (default: "gravity" in needs)
    # geometry: evaluate(geom, *args) -> RelationFact (tests and the verifier's independent path)
    evaluate: Callable[..., RelationFact] | None = field(default=None, compare=False, repr=False)
    # the instances a built graph stores (None: nothing stored), in storage order
    stored: Callable[[SceneGeom], list[RelationFact]] | None = field(default=None, compare=False, repr=False)
    # a stored graph's answer for one instance (mirrors and negations are derived from their base)
    cell: CellRule | None = field(default=None, compare=False, repr=False)
    # a stored graph's whole table (binary relations: code rows over the sorted ids; between: BetweenTable)
    table: TableRule | None = field(default=None, compare=False, repr=False)
    # the argument tuples `GraphIndex.instances` enumerates (default: every tuple of distinct objects)
    domain: Callable[[RelationTables], list[tuple[Any, ...]]] | None = field(default=None, compare=False, repr=False)
    # every instance at once, where instances are not determined by their arguments (free-space regions)
    instances: Callable[[RelationTables], list[RelationFact]] | None = field(default=None, compare=False, repr=False)

    gated: bool = field(init=False, compare=False, repr=False)  # evaluated only when gravity is known

    def __post_init__(self) -> None:
        object.__setattr__(self, "gated", ("gravity" in self.needs) if self.world_only is None else self.world_only)

    def to_json(self) -> dict[str, Any]:
        return {
            "id": self.id,
            "name": self.id.replace("_", " "),
            "group": self.group,
            "frame": self.frame,
            "arity": self.arity,
            "value": self.value,
            "margin": self.margin,
            "definition": self.definition,
            "sources": list(self.sources),
            "storage": self.storage,
            "mirror_of": self.mirror_of,
            "negation_of": self.negation_of,
            "needs": list(self.needs),
            "in_31": self.spec,
        }


REGISTRY: Registry[Relation] = Registry("relation")


def register(rel: Relation) -> Relation:
    REGISTRY.add(rel.id, rel)
    return rel


def decide(value: float, margin: float) -> bool | None:
    """True above +margin, False below -margin, None (undecided) inside the band."""
    if value > margin:
        return True
    if value < -margin:
        return False
    return None


def decide_band(value: float, low: float, high: float) -> bool | None:
    """True below `low`, False above `high`, None between (for "within a distance" relations)."""
    if value < low:
        return True
    if value > high:
        return False
    return None


def negate(f: RelationFact, relation: str | None = None, args: tuple[Any, ...] | None = None) -> RelationFact:
    return RelationFact(
        relation or f.relation,
        args if args is not None else f.args,
        None if f.holds is None else (not f.holds),
        -f.value,
        f.margin,
    )
