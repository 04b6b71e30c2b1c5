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
qa:
  families:
    locate: {{weight: 1.0, templates: [{templates}/locate.yaml]}}
    choice: {{weight: 1.0, templates: [{templates}/choice.yaml]}}
    quantitative: {{weight: 1.0, templates: [{templates}/quantitative.yaml]}}
    identify: {{weight: 1.0, templates: [{templates}/identify.yaml]}}
shards:
  samples_per_shard: {per_shard}
"""
TEMPLATES = Path(__file__).resolve().parents[2] / "recipes" / "templates"


def write_toy_recipe(folder: Path, scenes: int = 8, per_shard: int = 3) -> Path:
    p = folder / "toy.yaml"
    p.write_text(TOY_RECIPE.format(scenes=scenes, per_shard=per_shard, templates=TEMPLATES))
    return p


def output_digest(out: Path) -> dict[str, str]:
    """sha256 of every deterministic output file (shards and index), by name."""
    files = sorted(out.glob("shard-*.mcap")) + [out / "index.json"]
    return {f.name: hashlib.sha256(f.read_bytes()).hexdigest() for f in files}
