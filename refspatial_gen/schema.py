"""A tiny declarative schema for YAML sections: types, ranges, choices, unknown keys -> `file:line` errors.

Every part of the project that reads a recipe section (sources, qa, shards) declares its fields with
`Field` and calls `check_section`, so all recipe errors look the same and are all found before any work.
"""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import dataclass
from typing import Any

from refspatial_gen.core.errors import RecipeError
from refspatial_gen.yamlpos import line_of

_TYPE_NAMES = {
    int: "an integer",
    float: "a number",
    str: "a string",
    bool: "true/false",
    list: "a list",
    dict: "a mapping",
}


@dataclass(frozen=True)
class Field:
    type: type | tuple[type, ...]
    required: bool = False
    default: Any = None
    choices: tuple | None = None
    min: float | None = None
    max: float | None = None
    check: Callable[[Any], str | None] | None = None  # returns an error message or None
    doc: str = ""


def _type_ok(value: Any, t) -> bool:
    if isinstance(value, float) and not math.isfinite(value):
        return False  # NaN and infinity are never a valid setting (they pass every range check)
    ts = t if isinstance(t, tuple) else (t,)
    for ty in ts:
        if ty is float and isinstance(value, (int, float)) and not isinstance(value, bool):
            return True
        if ty is int and isinstance(value, int) and not isinstance(value, bool):
            return True
        if ty not in (int, float) and isinstance(value, ty):
            return True
    return False


def short(value: Any, limit: int = 60) -> str:
    """repr() cut to `limit` characters: an error message quotes a value, never pages of it."""
    r = repr(value)
    return r if len(r) <= limit else r[: limit - 3] + "..."


def _type_name(t) -> str:
    ts = t if isinstance(t, tuple) else (t,)
    return " or ".join(_TYPE_NAMES.get(x, x.__name__) for x in ts)


def check_section(
    data: Any, fields: dict[str, Field], file: str, lines: dict[tuple, int], path: tuple, errors: list[RecipeError]
) -> dict[str, Any]:
    """Validate one mapping; append every problem to `errors`; return the section with defaults filled in."""
    where = ".".join(str(p) for p in path) or "recipe"
    prefix = f"{where}." if path else ""
    if data is None:
        data = {}
    if not isinstance(data, dict):
        errors.append(RecipeError(file, line_of(lines, path), f"{where} must be a mapping, got {type(data).__name__}"))
        return {k: f.default for k, f in fields.items()}
    out: dict[str, Any] = {}
    for key in data:
        if key not in fields:
            known = ", ".join(sorted(fields))
            errors.append(
                RecipeError(
                    file, line_of(lines, path + (key,)), f"unknown key {short(key)} in {where} (known: {known})"
                )
            )
    for key, f in fields.items():
        if key not in data or data[key] is None:
            if f.required:
                errors.append(RecipeError(file, line_of(lines, path), f"{where}: missing required key {key!r}"))
            out[key] = f.default
            continue
        v = data[key]
        ln = line_of(lines, path + (key,))
        if isinstance(v, float) and not math.isfinite(v):
            errors.append(RecipeError(file, ln, f"{prefix}{key} must be a finite number, got {v}"))
            out[key] = f.default
            continue
        if not _type_ok(v, f.type):
            errors.append(
                RecipeError(file, ln, f"{prefix}{key} must be {_type_name(f.type)}, got {type(v).__name__} {short(v)}")
            )
            out[key] = f.default
            continue
        if isinstance(v, int) and not isinstance(v, bool) and f.type is float:
            v = float(v)
        if f.choices is not None and v not in f.choices:
            errors.append(
                RecipeError(file, ln, f"{prefix}{key} must be one of {', '.join(map(str, f.choices))}, got {short(v)}")
            )
        if f.min is not None and isinstance(v, (int, float)) and v < f.min:
            errors.append(RecipeError(file, ln, f"{prefix}{key} must be >= {f.min}, got {v}"))
        if f.max is not None and isinstance(v, (int, float)) and v > f.max:
            errors.append(RecipeError(file, ln, f"{prefix}{key} must be <= {f.max}, got {v}"))
        if f.check is not None:
            try:
                msg = f.check(v)
            except (TypeError, ValueError, KeyError, AttributeError) as e:  # a check meeting a shape it never expected
                msg = f"invalid value ({type(e).__name__})"
            if msg:
                errors.append(RecipeError(file, ln, f"{prefix}{key}: {msg}"))
        out[key] = v
    return out


def non_finite(data: Any, file: str, lines: dict[tuple, int], errors: list[RecipeError], path: tuple = ()) -> None:
    """NaN or infinity anywhere in a document (inside free-form mappings too: weights, options) is an error."""
    if isinstance(data, float) and not math.isfinite(data):
        where = ".".join(str(p) for p in path) or "value"
        errors.append(RecipeError(file, line_of(lines, path), f"{where} must be a finite number, got {data}"))
    elif isinstance(data, dict):
        for k, v in data.items():
            non_finite(v, file, lines, errors, path + (k,))
    elif isinstance(data, list):
        for i, v in enumerate(data):
            non_finite(v, file, lines, errors, path + (i,))
