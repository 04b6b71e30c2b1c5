"""The relation registry (`REGISTRY`, id -> Relation) and the modules that fill it.

Adding a relation: one module in this package (listed in MODULES) that registers a `Relation` with its
geometry (`evaluate`), what a graph stores (`stored`) and how a stored graph answers it (`cell`, and
`table` where a whole table pays; graph/relations/lookup.py has the rules of each storage kind); its
thresholds in graph/constants.py; a wording line in qa/lexicon.py; and a test with a holding, a failing and
an undecided case. docs/architecture.md walks through an example.
"""

from __future__ import annotations

import importlib
from typing import Any

from refspatial_gen.core.model import RelationFact
from refspatial_gen.graph.relations.base import REGISTRY, Relation, register

MODULES = (
    "refspatial_gen.graph.relations.directions",
    "refspatial_gen.graph.relations.vertical",
    "refspatial_gen.graph.relations.sizes",
    "refspatial_gen.graph.relations.distances",
    "refspatial_gen.graph.relations.orientation",
    "refspatial_gen.graph.relations.containment",
    "refspatial_gen.graph.relations.surface",
)
for _m in MODULES:
    importlib.import_module(_m)

# The 31 relation ids of shared/spec/relations.md, in the table's order.
SPEC_31 = (
    "left",
    "right",
    "close",
    "far",
    "depth",
    "above_world",
    "below_world",
    "above_image",
    "below_image",
    "tall",
    "short",
    "between",
    "rotation_horizontal",
    "rotation_vertical",
    "free_space",
    "corner",
    "edge",
    "angle",
    "distance",
    "front",
    "behind",
    "big",
    "small",
    "inside",
    "outside",
    "facing",
    "facing_away",
    "wide",
    "thin",
    "touching",
    "far_from",
)


def all_facts(geom: Any) -> list[RelationFact]:
    """Every stored fact of one frame, relation by relation in registration order (deterministic)."""
    out: list[RelationFact] = []
    for rel in REGISTRY.values():
        if rel.stored is not None and (geom.world_ok or not rel.gated):
            out += rel.stored(geom)
    return out


def evaluate(geom: Any, relation: str, *args: Any) -> RelationFact:
    """Evaluate one relation instance directly on the geometry (tests and verification)."""
    fn = REGISTRY[relation].evaluate
    if fn is None:
        raise ValueError(f"relation {relation!r} has no geometry evaluator")
    return fn(geom, *args)


def ids_by_use(kind: str) -> tuple[str, ...]:
    """Relation ids templates may use in the given way ("ordered", "pairwise", "anchored"), registry order."""
    return tuple(r.id for r in REGISTRY.values() if r.qa == kind)


def template_relations() -> tuple[str, ...]:
    """Relation ids a template may name: the 31 of the spec (spec order), then the extras with a QA use."""
    extra = tuple(r.id for r in REGISTRY.values() if r.qa and r.id not in SPEC_31)
    return SPEC_31 + extra


def listing() -> list[dict[str, Any]]:
    """The registry as JSON-able rows, the 31 first in the spec's order, then the extras."""
    spec = [REGISTRY[r] for r in SPEC_31]
    extra = sorted((r for r in REGISTRY.values() if r.id not in SPEC_31), key=lambda r: r.id)
    return [r.to_json() for r in spec + extra]


__all__ = [
    "REGISTRY",
    "SPEC_31",
    "Relation",
    "all_facts",
    "evaluate",
    "ids_by_use",
    "listing",
    "register",
    "template_relations",
]
