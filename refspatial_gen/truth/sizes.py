"""Category size ranges and the bearing table: independent evidence a lifted object is checked against.

    size_range("person")                    -> SizeRange(height=(0.5, 2.1), ...)   (None: unranged)
    check_size("car", (1.9, 4.4, 0.3))      -> "size_too_short"                   (None: plausible)
    can_bear("dining table", "cup")         -> True;  can_bear("car", "car") -> False

Why: `verify` proves answers agree with the stored scene; these checks compare the scene with what the
world allows, so a photo lifted 3.7 m tall person or a car "on" a car never reaches a question. The data
live in `truth/data/*.yaml` with their sources (docs/quality.md, "Truth checks"). A category without an
entry has no range: `size_range` returns None and `check_size` says `size_unranged`, so callers give it
no metric or size question rather than a guess.
"""

from __future__ import annotations

from collections.abc import Iterable, Sequence
from dataclasses import dataclass
from functools import lru_cache
from pathlib import Path
from typing import Any

DATA = Path(__file__).parent / "data"

# reasons check_size returns (also the keys counted in frame/graph meta["truth"])
TOO_TALL, TOO_SHORT = "size_too_tall", "size_too_short"
TOO_LONG, TOO_NARROW = "size_too_long", "size_too_narrow"
TOO_LARGE, TOO_SMALL = "size_too_large", "size_too_small"
UNRANGED = "size_unranged"
IMPLAUSIBLE = (TOO_TALL, TOO_SHORT, TOO_LONG, TOO_NARROW, TOO_LARGE, TOO_SMALL)

Range = tuple[float, float]


@dataclass(frozen=True)
class SizeRange:
    """Plausible extents (metres) of one category. `height`/`length` only for upright categories
    (vertical extent and largest horizontal extent in the usual pose); `extent` (largest of the three,
    any pose) always. `typical` is a typical height; `anchor` marks categories that usually stand on
    the ground in photos (they may fix a photo's scale)."""

    category: str
    extent: Range
    height: Range | None = None
    length: Range | None = None
    typical: float | None = None
    anchor: bool = False
    sources: tuple[str, ...] = ()


def normalise(category: str) -> str:
    """Dataset spelling -> lookup key: lower case, '_' as a space, single spaces."""
    return " ".join(str(category).replace("_", " ").lower().split())


def _range(v: Any, where: str) -> Range | None:
    if v is None:
        return None
    if not (
        isinstance(v, (list, tuple))
        and len(v) == 2
        and all(isinstance(x, (int, float)) for x in v)
        and 0 < v[0] <= v[1]
    ):
        raise ValueError(f"{where}: a range must be [lo, hi] with 0 < lo <= hi, got {v!r}")
    return float(v[0]), float(v[1])


def _load_yaml(name: str) -> dict:
    import yaml

    with open(DATA / name, encoding="utf-8") as f:
        return yaml.safe_load(f)


@lru_cache(maxsize=1)
def _sizes() -> tuple[dict[str, SizeRange], dict[str, str], dict[str, str]]:
    """(canonical name -> SizeRange, alias -> canonical name, source key -> citation)."""
    raw = _load_yaml("category_sizes.yaml")
    sources = {str(k): str(v) for k, v in (raw.get("sources") or {}).items()}
    out: dict[str, SizeRange] = {}
    for name, e in (raw.get("categories") or {}).items():
        key, where = normalise(name), f"category_sizes.yaml: {name}"
        src = tuple(str(s) for s in e.get("src") or ())
        missing = [s for s in src if s not in sources]
        if not src or missing:
            raise ValueError(f"{where}: every entry cites known sources (missing: {missing or 'src'})")
        ext = _range(e.get("extent"), where)
        if ext is None:
            raise ValueError(f"{where}: needs 'extent'")
        out[key] = SizeRange(
            key,
            ext,
            _range(e.get("height"), where),
            _range(e.get("length"), where),
            float(e["typical"]) if e.get("typical") is not None else None,
            bool(e.get("anchor", False)),
            src,
        )
    aliases = {normalise(a): normalise(c) for a, c in (raw.get("aliases") or {}).items()}
    bad = sorted(a for a, c in aliases.items() if c not in out)
    if bad:
        raise ValueError(f"category_sizes.yaml: aliases to unknown categories: {bad}")
    return out, aliases, sources


def canonical(category: str) -> str:
    """The name the data files use for `category` (aliases resolved; unknown names unchanged)."""
    _, aliases, _ = _sizes()
    key = normalise(category)
    return aliases.get(key, key)


def size_range(category: str) -> SizeRange | None:
    """The category's plausible size, or None when it has no honest range (no metric claims then)."""
    return _sizes()[0].get(canonical(category))


def ranged_categories() -> list[str]:
    return sorted(_sizes()[0])


def source_text(key: str) -> str:
    """The citation behind a source key of the data file."""
    return _sizes()[2][key]


def typical_height(category: str) -> float | None:
    r = size_range(category)
    return None if r is None else r.typical


def _out_of(v: float, rng: Range | None, tol: float, low: str, high: str, lower_bound: bool = False) -> str | None:
    if rng is None:
        return None
    lo, hi = rng
    if v > hi * (1.0 + tol):
        return high
    if not lower_bound and v < lo / (1.0 + tol):
        return low
    return None


def check_size(
    category: str,
    size_xyz: Sequence[float],
    dims: Iterable[str] = ("height", "length", "extent"),
    tolerance: float = 0.0,
    lower_bounds: Iterable[str] = (),
) -> str | None:
    """Why an object of `category` with this gravity-aligned box size (x, y horizontal, z vertical;
    metres) is implausible, or None when it is plausible.

    `dims` picks the checks: "height" (z vs the upright height range), "length" (largest horizontal
    extent), "extent" (largest of the three, any pose). `tolerance` widens every range by that
    fraction on both sides. Dims named in `lower_bounds` are only checked from above (a visible
    extent cut by the image border or an occluder is a lower bound on the real one).
    Unranged categories return `UNRANGED`: callers must not ask metric or size questions about them.
    """
    r = size_range(category)
    if r is None:
        return UNRANGED
    sx, sy, sz = (float(v) for v in size_xyz)
    lb = set(lower_bounds)
    want = set(dims)
    unknown = want - {"height", "length", "extent"}
    if unknown:
        raise ValueError(f"check_size: unknown dims {sorted(unknown)}")
    if "height" in want:
        why = _out_of(sz, r.height, tolerance, TOO_SHORT, TOO_TALL, "height" in lb)
        if why:
            return why
    if "length" in want:
        why = _out_of(max(sx, sy), r.length, tolerance, TOO_NARROW, TOO_LONG, "length" in lb)
        if why:
            return why
    if "extent" in want:
        why = _out_of(max(sx, sy, sz), r.extent, tolerance, TOO_SMALL, TOO_LARGE, "extent" in lb)
        if why:
            return why
    return None


# --------------------------------------------------------------------------------------------- bearing
@dataclass(frozen=True)
class _Bearing:
    bears: dict[str, frozenset[str]]  # bearer -> classes / categories it carries
    never: frozenset[str]
    groups: dict[str, str]  # category -> group name
    small: float
    medium: float
    overhang: float


@lru_cache(maxsize=1)
def _bearing() -> _Bearing:
    raw = _load_yaml("bearing.yaml")
    groups = {canonical(c): g for g, cats in (raw.get("groups") or {}).items() for c in cats}
    cls = raw.get("classes") or {}
    bears = {
        canonical(k): frozenset(
            canonical(x) if x not in ("any", "small", "medium") and x not in (raw.get("groups") or {}) else x
            for x in (v.get("bears") or ())
        )
        for k, v in (raw.get("bearers") or {}).items()
    }
    never = frozenset(canonical(c) for c in raw.get("never") or ())
    clash = sorted(never & set(bears))
    if clash:
        raise ValueError(f"bearing.yaml: categories both bearers and 'never': {clash}")
    return _Bearing(
        bears,
        never,
        groups,
        float(cls.get("small_max_extent", 0.5)),
        float(cls.get("medium_max_extent", 1.3)),
        float(raw.get("max_overhang", 1.5)),
    )


def object_class(category: str, size: Sequence[float] | None = None) -> str | None:
    """What `category` is for bearing: a group (person, animal_small, ...) or a size class (small,
    medium, large) from the object's own largest extent when `size` is given (clipped into the
    category's range), else from the top of its range; an unranged category outside every group is classed by
    its own `size` when given, else None."""
    b = _bearing()
    key = canonical(category)
    if key in b.groups:
        return b.groups[key]
    r = size_range(key)
    if r is None:
        if size is None:
            return None
        hi = max(float(v) for v in size)  # unranged: the object's own measured size is all there is
        return "small" if hi <= b.small else "medium" if hi <= b.medium else "large"
    hi = r.extent[1] if size is None else min(max(max(float(v) for v in size), r.extent[0]), r.extent[1])
    return "small" if hi <= b.small else "medium" if hi <= b.medium else "large"


def can_bear(
    support_category: str,
    object_category: str,
    support_size: Sequence[float] | None = None,
    object_size: Sequence[float] | None = None,
    unknown: bool = False,
) -> bool:
    """Can an object of `support_category` carry one of `object_category` on its top?

    Category rule from bearing.yaml (a table carries a cup; a car, a bus, a person or an umbrella
    carries nothing); when both box sizes (x, y, z metres) are given, the carried object's largest
    horizontal extent may exceed the bearer's by at most `max_overhang` (a car never rests on a cup).
    `unknown` is the answer for a support category the table does not list (default: no).
    """
    b = _bearing()
    sup, obj = canonical(support_category), canonical(object_category)
    if sup in b.never:
        return False
    allowed = b.bears.get(sup)
    if allowed is None:
        return bool(unknown)
    if "any" not in allowed and obj not in allowed and object_class(obj, object_size) not in allowed:
        return False
    if support_size is not None and object_size is not None:
        if max(object_size[0], object_size[1]) > b.overhang * max(support_size[0], support_size[1]):
            return False
    return True


def bearer_categories() -> list[str]:
    return sorted(_bearing().bears)


__all__ = [
    "IMPLAUSIBLE",
    "SizeRange",
    "UNRANGED",
    "bearer_categories",
    "can_bear",
    "canonical",
    "check_size",
    "normalise",
    "object_class",
    "ranged_categories",
    "size_range",
    "source_text",
    "typical_height",
]
