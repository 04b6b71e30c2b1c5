"""index.json beside the shards: every shard with its counts, size and sha256, plus the run's identity.

Why canonical JSON and no times or hosts: two identical runs must write identical index bytes, so the
index can itself be compared and hashed. Run-varying facts go in the run log, never here.
"""

from __future__ import annotations

import json
import os
from pathlib import Path
from typing import Any

from refspatial_gen import SCHEMA_VERSION
from refspatial_gen.core.serialize import dumps

INDEX_NAME = "index.json"
_REQUIRED_SHARD_KEYS = ("name", "samples", "qa_pairs", "bytes", "sha256")
_FORBIDDEN_RUN_KEYS = ("time", "timestamp", "started", "finished", "host", "hostname", "duration", "elapsed")


def _sort_deep(obj: Any) -> Any:
    """Dict keys are sorted by dumps; lists are kept in their given order (they carry meaning)."""
    if isinstance(obj, dict):
        return {str(k): _sort_deep(v) for k, v in obj.items()}
    if isinstance(obj, (list, tuple)):
        return [_sort_deep(v) for v in obj]
    return obj


def build_index(shards: list[dict], run_info: dict) -> dict:
    """The index as a dict: shards sorted by name, totals, and run_info (recipe, seed, code version, ...)."""
    rows = []
    for s in shards:
        d = dict(s.to_dict() if hasattr(s, "to_dict") else s)
        missing = [k for k in _REQUIRED_SHARD_KEYS if k not in d]
        if missing:
            raise ValueError(f"shard entry {d.get('name', '?')!r} lacks {', '.join(missing)}")
        problem = shard_name_problem(d["name"])
        if problem:
            raise ValueError(f"shard entry name {d['name']!r} {problem}")
        rows.append(_sort_deep(d))
    names = [r["name"] for r in rows]
    if len(set(names)) != len(names):
        raise ValueError("duplicate shard names in index")
    bad = [k for k in run_info if k.lower() in _FORBIDDEN_RUN_KEYS]
    if bad:
        raise ValueError(f"run_info must not hold run-varying keys {bad}: put them in the run log")
    rows.sort(key=lambda r: r["name"])
    return {
        "schema_version": SCHEMA_VERSION,
        "kind": "shard_index",
        **_sort_deep(dict(run_info)),
        "shards": rows,
        "totals": {
            "shards": len(rows),
            "samples": sum(int(r["samples"]) for r in rows),
            "qa_pairs": sum(int(r["qa_pairs"]) for r in rows),
            "bytes": sum(int(r["bytes"]) for r in rows),
        },
    }


def write_index(out_dir: Path | str, shards: list[dict], run_info: dict) -> dict:
    """Write `out_dir/index.json` atomically (temp name + rename); returns the index as written."""
    out_dir = Path(out_dir)
    out_dir.mkdir(parents=True, exist_ok=True)
    index = build_index(shards, run_info)
    data = dumps(index) + b"\n"
    tmp = out_dir / (INDEX_NAME + ".partial")
    with open(tmp, "wb") as f:
        f.write(data)
        f.flush()
        os.fsync(f.fileno())
    os.replace(tmp, out_dir / INDEX_NAME)
    return index


def read_index(out_dir: Path | str) -> dict:
    """Parse `out_dir/index.json` (or the given index file). Raises ValueError naming the file on problems."""
    p = Path(out_dir)
    if p.is_dir():
        p = p / INDEX_NAME
    try:
        d = json.loads(p.read_bytes())
    except FileNotFoundError:
        raise ValueError(f"{p}: no index.json (not a shard directory, or the run has not finished)") from None
    except (json.JSONDecodeError, UnicodeDecodeError) as e:
        raise ValueError(f"{p}: index.json is not valid JSON ({e})") from None
    if not isinstance(d, dict) or not isinstance(d.get("shards"), list):
        raise ValueError(f"{p}: index.json has no 'shards' list")
    if d.get("schema_version") != SCHEMA_VERSION:
        raise ValueError(
            f"{p}: schema_version {d.get('schema_version')!r} not supported (this code reads {SCHEMA_VERSION})"
        )
    for i, s in enumerate(d["shards"]):
        if not isinstance(s, dict):
            raise ValueError(f"{p}: shards[{i}] is {type(s).__name__}, not an object")
        problem = shard_name_problem(s.get("name"))
        if problem:
            raise ValueError(f"{p}: shards[{i}] name {s.get('name')!r} {problem}; refusing to open it")
    return d


def shard_name_problem(name: Any) -> str | None:
    """Why `name` may not be opened as a shard of the index's folder (None = a plain file name there).

    Why: readers join names from index.json to the dataset folder; an edited index must not make them
    open `../../etc/passwd` or an absolute path.
    """
    if not isinstance(name, str) or not name:
        return "is not a file name"
    if "/" in name or "\\" in name or "\0" in name:
        return "contains a path separator or NUL (must be a plain file name in the index's folder)"
    if name in (".", "..") or name.startswith(".."):
        return "points outside the index's folder"
    if name.startswith("."):
        return "is a hidden file name"
    return None


def shard_paths(out_dir: Path | str) -> list[Path]:
    """The shard files an index lists, in index order."""
    out_dir = Path(out_dir)
    return [out_dir / s["name"] for s in read_index(out_dir)["shards"]]
