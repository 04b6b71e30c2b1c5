"""Scene sources. Each registers itself by name; a recipe picks sources by that name.

A source turns a *unit key* (a deterministic string fixed at planning time) into one or more Frames.
Bad input raises `refspatial_gen.core.errors.DropUnit(reason, detail)`: the run drops that unit, counts
the reason, and goes on.
"""

from __future__ import annotations

import importlib
from typing import Any, Protocol

import numpy as np

from refspatial_gen.core.model import Frame


class SceneSource(Protocol):
    """What every source provides. `config` is the source's section of the recipe (already validated)."""

    name: str

    def unit_keys(self, config: dict[str, Any], scenes: int | None, input_path: str | None) -> list[str]:
        """The deterministic list of work units (e.g. "sim:000017" or "scan:sunrgbd/000001")."""
        ...

    def load(self, unit_key: str, rng: np.random.Generator, config: dict[str, Any]) -> list[Frame]:
        """Frames for one unit (several for multi-view). Raise DropUnit on bad input."""
        ...


# name -> "module:attribute" (imported lazily so heavy dependencies load only when used)
_SOURCES: dict[str, str] = {
    "toy": "refspatial_gen.sources.toy:ToySource",
    "sim": "refspatial_gen.sources.sim:SimSource",
    "image": "refspatial_gen.sources.image:ImageSource",
    "scan": "refspatial_gen.sources.scan:ScanSource",
}


def register_source(name: str, target: str) -> None:
    _SOURCES[name] = target


def source_names() -> list[str]:
    return sorted(_SOURCES)


def get_source(name: str) -> SceneSource:
    if name not in _SOURCES:
        raise KeyError(f"unknown source {name!r} (known: {', '.join(source_names())})")
    mod, attr = _SOURCES[name].split(":")
    return getattr(importlib.import_module(mod), attr)()
