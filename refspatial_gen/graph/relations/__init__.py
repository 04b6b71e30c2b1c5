"""The relation registry (`REGISTRY`, id -> Relation) and the group modules that fill it.

Adding a relation: add it to a group module (or a new module listed in GROUPS) with `register(...)`
and emit its stored instances from that module's `facts(geom)`; add a test with a holding, a failing
and an undecided case.
"""

from __future__ import annotations

import importlib

from refspatial_gen.core.model import RelationFact
from refspatial_gen.graph.relations.base import REGISTRY, Relation, register

GROUPS = (
    "refspatial_gen.graph.relations.directions",
    "refspatial_gen.graph.relations.vertical",
    "refspatial_gen.graph.relations.sizes",
    "refspatial_gen.graph.relations.distances",
    "refspatial_gen.graph.relations.orientation",
    "refspatial_gen.graph.relations.containment",
    "refspatial_gen.graph.relations.surface",
)
_MODULES = [importlib.import_module(m) for m in GROUPS]

# The 31 relation ids of shared/spec/relations.md, in the table's order.
SPEC_31 = ("left", "right", "close", "far", "depth", "above_world", "below_world", "above_image", "below_image",
           "tall", "short", "between", "rotation_horizontal", "rotation_vertical", "free_space", "corner", "edge",
           "angle", "distance", "front", "behind", "big", "small", "inside", "outside", "facing", "facing_away",
           "wide", "thin", "touching", "far_from")


def all_facts(geom) -> list[RelationFact]:
    """Every stored fact of one frame, group by group (deterministic order)."""
    out: list[RelationFact] = []
    for m in _MODULES:
        out += m.facts(geom)
    return out


def evaluate(geom, relation: str, *args) -> RelationFact:
    """Evaluate one relation instance directly on the geometry (tests and verification)."""
    rel = REGISTRY[relation]
    return rel.evaluate(geom, *args)


def listing() -> list[dict]:
    """The registry as JSON-able rows, the 31 first in the spec's order, then the extras."""
    spec = [REGISTRY[r] for r in SPEC_31]
    extra = sorted((r for r in REGISTRY.values() if r.id not in SPEC_31), key=lambda r: r.id)
    return [r.to_json() for r in spec + extra]


__all__ = ["REGISTRY", "Relation", "SPEC_31", "all_facts", "evaluate", "listing", "register"]
