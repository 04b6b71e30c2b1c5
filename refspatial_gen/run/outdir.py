"""The output folder of a run: its identity (`_parts/run.json`), `--fresh`, leftovers and stray files.

The run's fingerprint is the recipe's (recipe hash, seed, scenes, code version) plus, for every source
with an input folder, that input's content digest (run/manifest.py). Resuming into a folder whose
fingerprint differs is refused, naming what differs; `--fresh` replaces the old run (only while this
run holds the folder's lock, see run/lock.py).
"""

from __future__ import annotations

import json
import re
from collections.abc import Iterable
from pathlib import Path
from typing import Any

from refspatial_gen.core.errors import RunError
from refspatial_gen.core.fsutil import atomic_write_bytes
from refspatial_gen.core.serialize import dumps
from refspatial_gen.recipe import Recipe, recipe_fingerprint
from refspatial_gen.run.manifest import input_manifest

PARTS = "_parts"


def run_fingerprint(recipe: Recipe, out_dir: Path) -> dict[str, Any]:
    """recipe_fingerprint plus each input's content digest (hashes cached in _parts/input-<n>.json)."""
    fp = recipe_fingerprint(recipe)
    (out_dir / PARTS).mkdir(parents=True, exist_ok=True)
    for entry, spec in zip(fp["sources"], recipe.sources):
        if spec.input is None:
            continue
        m = input_manifest(spec.input, out_dir / PARTS / f"input-{spec.index}.json")
        entry["input_files"], entry["input_bytes"], entry["input_digest"] = m["files"], m["bytes"], m["digest"]
    return fp


def _differences(old: Any, new: dict[str, Any]) -> list[str]:
    if not isinstance(old, dict):
        return ["unreadable run record"]
    out = [k for k in ("recipe_hash", "seed", "scenes", "code_version") if old.get(k) != new.get(k)]
    olds, news = old.get("sources") or [], new.get("sources") or []
    if len(olds) != len(news):
        out.append("sources")
    for i, (a, b) in enumerate(zip(olds, news)):
        if not isinstance(a, dict):
            out.append(f"sources[{i}]")
            continue
        if a.get("input_digest") != b.get("input_digest") or a.get("input") != b.get("input"):
            out.append(f"input of sources[{i}] (content differs)")
        elif {k: v for k, v in a.items() if not k.startswith("input")} != {
            k: v for k, v in b.items() if not k.startswith("input")
        }:
            out.append(f"sources[{i}]")
    return out or ["run record"]


def prepare(out_dir: Path, fingerprint: dict[str, Any], fresh: bool) -> None:
    """Refuse a different run's folder (unless `fresh`), clear it when `fresh`, remove half-written files."""
    marker = out_dir / PARTS / "run.json"
    if marker.is_file() and not fresh:
        try:
            old = json.loads(marker.read_bytes())
        except (OSError, ValueError):
            old = None
        if old != fingerprint:
            raise RunError(
                f"{out_dir} holds the output of a different run ({', '.join(_differences(old, fingerprint))} "
                f"differ); use another --out or pass --fresh to replace it",
                2,
            )
    if fresh:
        for p in list(out_dir.glob("shard-*")) + [out_dir / "index.json", out_dir / "run_log.json"]:
            if p.is_file():
                p.unlink()
        for p in (out_dir / PARTS).glob("*"):
            if p.is_file() and not p.name.startswith("input-"):  # the input hash cache stays valid
                p.unlink()
    (out_dir / PARTS).mkdir(parents=True, exist_ok=True)
    # leftovers of a killed run: a half-written index or group record (shard partials are redone per group)
    for p in [out_dir / "index.json.partial", *(out_dir / PARTS).glob("*.tmp")]:
        if p.is_file():
            p.unlink()
    atomic_write_bytes(marker, dumps(fingerprint))


def group_files(out_dir: Path, index: int) -> list[Path]:
    stem = f"shard-{index:05d}"
    return sorted(p for p in out_dir.iterdir() if p.name.startswith(stem + ".") or p.name.startswith(stem + "-"))


def discard_groups(out_dir: Path, indices: Iterable[int]) -> None:
    """Delete what unfinished groups left (partial shards, unit markers): they are redone on resume."""
    for idx in indices:
        for p in group_files(out_dir, idx):
            p.unlink(missing_ok=True)
        (out_dir / PARTS / f"shard-{idx:05d}.unit").unlink(missing_ok=True)


def remove_strays(out_dir: Path, keep: set[str], groups: int) -> list[str]:
    """Shard files the index will not list (another run's, a group past this plan, partials), and group
    records past the plan: deleted before the index is written, so the folder holds exactly the index."""
    gone = []
    for p in sorted(out_dir.glob("shard-*")):
        if p.is_file() and p.name not in keep:
            p.unlink()
            gone.append(p.name)
    for p in sorted((out_dir / PARTS).glob("shard-*")):
        m = re.match(r"^shard-(\d{5})\.", p.name)
        if p.is_file() and (p.suffix == ".unit" or (m and int(m.group(1)) >= groups)):
            p.unlink()
    return gone
