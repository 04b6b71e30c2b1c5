"""The recipe's `graph:` section, checked before any work (file:line errors).

Why a schema: every key is read with `.get()` deep in the graph builder, so a misspelt key or a threshold
given as text used to be ignored silently (the reliability harness found `graph.thresholds` accepting
anything). Keys: `scale` (a preset name), `thresholds` (overrides of graph/constants.py Thresholds),
`fit_gravity`, `free_space`, and `truth` (graph/visibility.py)."""

from __future__ import annotations

from dataclasses import fields
from typing import Any

from refspatial_gen.core.errors import RecipeError
from refspatial_gen.graph.constants import PRESETS, Thresholds
from refspatial_gen.graph.visibility import check_truth_section
from refspatial_gen.schema import Field, check_section

GRAPH_FIELDS: dict[str, Field] = {
    "scale": Field(str, choices=tuple(sorted(PRESETS)), doc="threshold preset (default: decided per frame)"),
    "thresholds": Field(dict, default=None, doc="overrides of graph/constants.py Thresholds, by field name"),
    "fit_gravity": Field(bool, default=True, doc="refine gravity from a fitted support plane"),
    "free_space": Field(bool, default=True, doc="compute free-space regions for placement questions"),
    "truth": Field(dict, default=None, doc="visibility floor and metric trust (graph/visibility.py)"),
}
PX_MAX = {"min_surface_px": 1_000_000.0}  # pixel counts (at 640x480) go past 1000
THRESHOLD_FIELDS: dict[str, Field] = {
    f.name: Field(float, min=0.0, max=PX_MAX.get(f.name, 1_000.0), doc="graph/constants.py Thresholds")
    for f in fields(Thresholds)
}
THRESHOLD_FIELDS["corner_point_max_share"] = Field(
    float, min=0.0, max=1.0, doc="share of a surface's extent a corner/edge answer point may lie from it"
)


def check_graph_section(graph: Any, file: str, lines: dict[tuple[Any, ...], int], errors: list[RecipeError]) -> None:
    """Recipe check of `graph:`: known keys and types, every threshold override a known finite number."""
    if graph is None:
        return
    top = check_section(graph, GRAPH_FIELDS, file, lines, ("graph",), errors)
    if isinstance(top, dict) and isinstance(top.get("thresholds"), dict):
        check_section(top["thresholds"], THRESHOLD_FIELDS, file, lines, ("graph", "thresholds"), errors)
    check_truth_section(graph, file, lines, errors)
