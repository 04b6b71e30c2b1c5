"""Unit keys of the image source: `image:<image id>`, with no folder, so moving or copying the collection
changes neither the keys nor (the unit's random generator derives from the key) the output bytes."""

from __future__ import annotations

from pathlib import Path
from typing import Any

from refspatial_gen.core.errors import DropUnit

KEY_PREFIX = "image:"


def unit_key(image_id: str) -> str:
    """`image:<image id>` (the id as the annotations give it; no folder, see the module docstring)."""
    return f"{KEY_PREFIX}{image_id}"


def parse_key(key: str) -> str:
    """`image:<image id>` -> image id."""
    if not key.startswith(KEY_PREFIX) or len(key) == len(KEY_PREFIX):
        raise DropUnit("bad_unit_key", key)
    return key[len(KEY_PREFIX) :]


def input_root(config: dict[str, Any]) -> Path:
    """The collection folder unit keys resolve against (`_input`, set by the recipe loader from --input/`input:`)."""
    base = (config or {}).get("_input")
    if not base:
        raise ValueError(
            "image load() needs config['_input'] (the input folder; the recipe loader sets it "
            "from --input or the recipe's `input:`)"
        )
    return Path(base).resolve()
