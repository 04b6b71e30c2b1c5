"""Helpers for end-to-end run tests: small toy-source recipes and byte comparison of output folders."""

from __future__ import annotations

import hashlib
from pathlib import Path

TOY_RECIPE = """\
name: toy-test
seed: 11
scenes: {scenes}
sources:
  - kind: toy
    config: {{min_objects: 4, max_objects: 7}}
shards:
  samples_per_shard: {per_shard}
"""


def write_toy_recipe(folder: Path, scenes: int = 8, per_shard: int = 3) -> Path:
    p = folder / "toy.yaml"
    p.write_text(TOY_RECIPE.format(scenes=scenes, per_shard=per_shard))
    return p


def output_digest(out: Path) -> dict[str, str]:
    """sha256 of every deterministic output file (shards and index), by name."""
    files = sorted(out.glob("shard-*.mcap")) + [out / "index.json"]
    return {f.name: hashlib.sha256(f.read_bytes()).hexdigest() for f in files}
