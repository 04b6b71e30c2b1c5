"""The relation registry: every relation declares its frame, arity, metric, margin, sources and rule.

Why: the QA engine, `refspatial-gen relations`, the stats and the tests all read one table. Each group
module (one file per relation group) registers its relations with `register(...)` and provides
`facts(geom)`, the stored instances for one frame.

Storage kinds (keep stored graphs compact):
- "pair": antisymmetric comparison; one fact per unordered pair, stored as (lower position, higher);
  R(b, a) is the negation of R(a, b) with the value negated. Mirrors (right of left) swap arguments.
- "symmetric": one fact per unordered pair; R(a, b) == R(b, a).
- "unary": one fact per object (quantities such as depth or rotation angles).
- "sparse": only holding (True) and undecided (None) instances are stored; an evaluated instance that
  is absent is False. `domain` says which argument tuples were evaluated.
- "derived": not stored; computed by the query index from stored facts (close/far from distances).
- "region": answered by free-space regions (free_space).
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Callable

from refspatial_gen.core.model import RelationFact

ALL_SOURCES = ("sim", "toy", "scan", "image")
FRONT_SOURCES = ("sim", "toy", "scan*", "image*")  # * = only when the annotation gives a front direction
SURFACE_SOURCES = ("sim", "toy", "scan")


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
    mirror_of: str | None = None  # this relation is `mirror_of` with arguments reversed (binary)
    negation_of: str | None = None  # this relation is the negation of `negation_of` (same arguments)
    needs: tuple[str, ...] = ()  # "gravity", "front", "surface"
    spec: bool = True  # one of the 31 of shared/spec/relations.md
    evaluate: Callable[..., RelationFact] | None = field(default=None, compare=False, repr=False)

    def to_json(self) -> dict:
        return {"id": self.id, "name": self.id.replace("_", " "), "group": self.group, "frame": self.frame,
                "arity": self.arity, "value": self.value, "margin": self.margin, "definition": self.definition,
                "sources": list(self.sources), "storage": self.storage, "mirror_of": self.mirror_of,
                "negation_of": self.negation_of, "needs": list(self.needs), "in_31": self.spec}


REGISTRY: dict[str, Relation] = {}


def register(rel: Relation) -> Relation:
    if rel.id in REGISTRY:
        raise ValueError(f"relation {rel.id!r} registered twice")
    REGISTRY[rel.id] = rel
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


def negate(f: RelationFact, relation: str | None = None, args: tuple | None = None) -> RelationFact:
    return RelationFact(relation or f.relation, args if args is not None else f.args,
                        None if f.holds is None else (not f.holds), -f.value, f.margin)
