"""The receptacle table: which categories can hold which others inside them (truth/data/containers.yaml).

    can_contain("bowl", "apple")            -> True
    can_contain("desk", "garbage bin")      -> False  (a desk's knee space is not "in the desk")
    can_contain("bowl", "apple", (0.15, 0.15, 0.07), (0.5, 0.5, 0.3), max_overhang=1.2)  -> False (does not fit)

Why: "inside" was the share of A's box volume in B's box, so anything standing in a desk's, a table's or a
sofa's box was "in" it (audit round 4: "the bin in the desk"). A person says "in" for a receptacle; this
table says which categories are receptacles and for what (the object's class as bearing.yaml defines it).
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass
from functools import lru_cache

from refspatial_gen.truth.sizes import _load_yaml, canonical, object_class

CLASSES = ("small", "medium", "person", "animal_small", "animal_large", "ride", "vehicle", "any")


@dataclass(frozen=True)
class _Containers:
    holds: dict[str, frozenset[str]]  # container -> classes / categories it holds
    why: dict[str, str]
    never: frozenset[str]


@lru_cache(maxsize=1)
def _containers() -> _Containers:
    raw = _load_yaml("containers.yaml") or {}
    holds: dict[str, frozenset[str]] = {}
    why: dict[str, str] = {}
    for name, e in (raw.get("containers") or {}).items():
        if not isinstance(e, dict) or not e.get("holds") or not e.get("why"):
            raise ValueError(f"containers.yaml: {name}: needs 'holds' (a list) and 'why', got {e!r}")
        key = canonical(name)
        holds[key] = frozenset(x if x in CLASSES else canonical(x) for x in e["holds"])
        why[key] = str(e["why"])
    never = frozenset(canonical(c) for c in raw.get("not_containers") or ())
    clash = sorted(never & set(holds))
    if clash:
        raise ValueError(f"containers.yaml: categories both containers and not: {clash}")
    return _Containers(holds, why, never)


def fits(container_size: Sequence[float], object_size: Sequence[float], max_overhang: float) -> bool:
    """The object's largest horizontal extent is at most `max_overhang` times the container's (x, y, z sizes)."""
    return max(float(object_size[0]), float(object_size[1])) <= max_overhang * max(
        float(container_size[0]), float(container_size[1])
    )


def can_contain(
    container_category: str,
    object_category: str,
    container_size: Sequence[float] | None = None,
    object_size: Sequence[float] | None = None,
    max_overhang: float | None = None,
) -> bool:
    """Can an object of `container_category` hold one of `object_category` inside it? The category rule of
    containers.yaml (unlisted categories hold nothing), the object classed by its own size when given; with
    both sizes and `max_overhang`, the object must also fit (`fits`)."""
    c = _containers()
    key, obj = canonical(container_category), canonical(object_category)
    allowed = c.holds.get(key)
    if allowed is None:
        return False
    if "any" not in allowed and obj not in allowed and object_class(obj, object_size) not in allowed:
        return False
    if max_overhang is not None and container_size is not None and object_size is not None:
        return fits(container_size, object_size, max_overhang)
    return True


def container_categories() -> list[str]:
    return sorted(_containers().holds)


def why_container(category: str) -> str | None:
    """The rationale of the table for `category`, None when it holds nothing."""
    return _containers().why.get(canonical(category))
