"""The values steps pass to one another (points, options, numbers) and what a step may read (Context)."""

from __future__ import annotations

from dataclasses import dataclass
from typing import TYPE_CHECKING, Any

from refspatial_gen.core.model import FreeSpaceRegion

if TYPE_CHECKING:
    import numpy as np

    from refspatial_gen.qa.index import SceneIndex
    from refspatial_gen.qa.sample_rng import SampleRng


@dataclass(frozen=True)
class PointValue:
    point: tuple[float, float]
    object_id: int | None = None
    region: FreeSpaceRegion | None = None


@dataclass(frozen=True)
class OptionValue:
    options: tuple[Any, ...]  # object ids, or words ("left", "right")
    correct: int
    marks: bool = False


@dataclass(frozen=True)
class NumberValue:
    value: float  # SI: metres or radians
    quantity: str


@dataclass
class Context:
    """What a program may read besides the frame's index: the other frame of a multi-view pair."""

    idx: SceneIndex
    rng: np.random.Generator | SampleRng  # generation passes the sample's SampleRng
    second: SceneIndex | None = None
    prune: bool = True  # early-pruning bounds on (off when replaying a program for the degeneracy check)
