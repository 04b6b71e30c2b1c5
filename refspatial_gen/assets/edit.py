"""`refspatial-gen assets set-front NAME +x "the handle side"`: set a category's semantic front in place.

The front is a direction in the object frame (z up, as `assets sheet` draws it). The file that defines
the category is edited line by line, so its comments and layout stay as they were.
"""

from __future__ import annotations

import json
import re
from pathlib import Path

from refspatial_gen.assets.catalog import DEFAULT_CATALOG, Catalog, Category
from refspatial_gen.assets.importer import parse_axis


def find_category(cat: Catalog, name: str) -> Category:
    """By exact name, else by a unique label."""
    if name in cat.categories:
        return cat.categories[name]
    by_label = [c for c in cat.categories.values() if c.label == name]
    if len(by_label) == 1:
        return by_label[0]
    hint = f" (labels match: {', '.join(c.name for c in by_label)})" if by_label else ""
    raise KeyError(f"no category {name!r} in {cat.path}{hint}")


def set_front(cat: Catalog, name: str, direction: str, phrase: str) -> tuple[str, list[float]]:
    """Write `front` and `front_phrase` of category `name` into the file defining it; returns (file, front)."""
    c = find_category(cat, name)
    try:
        v = parse_axis(direction if "," not in direction else [float(x) for x in direction.split(",")])
    except ValueError:
        v = None
    if v is None:
        raise ValueError(f"direction {direction!r}: use +x, -x, +y, -y, +z, -z or 'x,y,z'")
    if not phrase.strip():
        raise ValueError('the front needs a phrase, e.g. "the handle side"')
    file, line = c.origin
    if Path(file).resolve() != Path(cat.path).resolve() and Path(file).resolve() == DEFAULT_CATALOG.resolve():
        raise ValueError(
            f"{c.name!r} comes from the built-in catalog through include:; give the name of one of "
            f"{cat.path}'s own categories (or edit the built-in catalog with --catalog {DEFAULT_CATALOG})"
        )
    lines = Path(file).read_text().splitlines(keepends=True)
    i = line - 1
    indent = len(lines[i]) - len(lines[i].lstrip())
    end = i + 1
    while end < len(lines) and (not lines[end].strip() or len(lines[end]) - len(lines[end].lstrip()) > indent):
        end += 1
    key_indent = " " * (indent + 2)
    front = [round(float(x), 4) for x in v]
    new = {
        "front": f"{key_indent}front: {json.dumps(front)}\n",
        "front_phrase": f"{key_indent}front_phrase: {json.dumps(phrase)}\n",
    }
    for key in ("front", "front_phrase"):
        pat = re.compile(rf"^{key_indent}{key}:")
        hit = next((k for k in range(i + 1, end) if pat.match(lines[k])), None)
        if hit is not None:
            lines[hit] = new[key]
        else:
            lines.insert(i + 1, new[key])
            end += 1
            i += 1
    Path(file).write_text("".join(lines))
    return file, front
