"""Which shard groups a resumed run keeps: a group counts as done only when its record exists and every
shard it lists matches its size and sha256 (run/executor.py)."""

from __future__ import annotations

import json
from pathlib import Path
from typing import Any

from refspatial_gen.core.fsutil import sha256_file
from refspatial_gen.run.outdir import PARTS
from refspatial_gen.run.plan import Group


def completed_record(out_dir: Path, group: Group) -> dict[str, Any] | None:
    """The group's record if the group finished and its shards are intact, else None (redo it)."""
    p = out_dir / PARTS / f"{group.name}.json"
    if not p.is_file():
        return None
    try:
        record = json.loads(p.read_bytes())
    except (OSError, ValueError):
        return None
    if (
        not isinstance(record, dict)
        or record.get("units") != [u.uid for u in group.units]
        or not isinstance(record.get("shards"), list)
        or not isinstance(record.get("stats"), dict)
    ):
        return None
    for s in record["shards"]:
        name = s.get("name") if isinstance(s, dict) else None
        if not isinstance(name, str) or not name.startswith(group.name) or "/" in name or "\\" in name:
            return None  # a record never names a file outside its own group's shards
        f = out_dir / name
        try:
            if not f.is_file() or f.stat().st_size != s.get("bytes") or sha256_file(f) != s.get("sha256"):
                return None
        except OSError:
            return None
    return record
