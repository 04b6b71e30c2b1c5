"""Scene sources. Each registers itself by name; a recipe picks sources by that name.

A source turns a *unit key* (a deterministic string fixed at planning time) into one or more Frames.
Bad input raises `refspatial_gen.core.errors.DropUnit(reason, detail)`: the run drops that unit, counts
the reason, and goes on.
"""

from __future__ import annotations

from typing import Any, Protocol

import numpy as np

from refspatial_gen.core.model import Frame
from refspatial_gen.core.registry import Registry


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
SOURCES: Registry[type] = Registry("source")
SOURCES.add("toy", "refspatial_gen.sources.toy:ToySource")
SOURCES.add("sim", "refspatial_gen.sources.sim:SimSource")
SOURCES.add("image", "refspatial_gen.sources.image:ImageSource")
SOURCES.add("scan", "refspatial_gen.sources.scan:ScanSource")


def register_source(name: str, target: str) -> None:
    SOURCES.add(name, target, replace=True)


def source_names() -> list[str]:
    return sorted(SOURCES.names())


def get_source(name: str) -> SceneSource:
    return SOURCES.get(name)()  # type: ignore[no-any-return]
