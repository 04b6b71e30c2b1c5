"""Model outputs on disk, keyed by (image content hash, model folder hash, settings), so a resume or a
second recipe over the same photos never runs a model twice.

One entry = one `.npz` (arrays plus a JSON string of small values) under `<cache_dir>/<stage>/<k[:2]>/<k>.npz`,
written to a temporary name and renamed, so a killed worker never leaves half an entry, and two workers
writing the same entry write the same bytes. The worker also keeps its most recent outputs in memory (with
or without the disk cache), so the other photos of a block, computed together, are not computed again.
What varies between runs (hits, timings) is never stored in the output.
"""

from __future__ import annotations

import hashlib
import io
import json
import os
from collections import OrderedDict
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from refspatial_gen.core.serialize import dumps


def default_dir() -> Path:
    base = os.environ.get("REFSPATIAL_CACHE")
    if base:
        return Path(base).expanduser() / "perception"
    xdg = os.environ.get("XDG_CACHE_HOME") or str(Path.home() / ".cache")
    return Path(xdg) / "refspatial-gen" / "perception"


def key_of(*parts: Any) -> str:
    """sha256 of the parts as canonical JSON (sorted keys)."""
    return hashlib.sha256(dumps(list(parts))).hexdigest()


def content_hash(data: bytes) -> str:
    return hashlib.sha256(data).hexdigest()


def array_hash(a: np.ndarray) -> str:
    """Hash of an image array (shape, dtype and bytes): frames read from scans have no file of their own."""
    h = hashlib.sha256(f"{a.shape}{a.dtype}".encode())
    h.update(np.ascontiguousarray(a).tobytes())
    return h.hexdigest()


MEMORY_ENTRIES = 64  # recent outputs kept in the worker, disk cache or not (a block's other photos come next)


@dataclass
class Cache:
    root: Path | None  # None: no disk cache (only the worker's recent outputs are kept, in memory)
    hits: dict[str, int] = field(default_factory=dict)
    misses: dict[str, int] = field(default_factory=dict)
    memory: OrderedDict = field(default_factory=OrderedDict)

    def _path(self, stage: str, key: str) -> Path:
        assert self.root is not None
        return self.root / stage / key[:2] / f"{key}.npz"

    def remember(self, stage: str, key: str, value: tuple[dict[str, np.ndarray], dict[str, Any]]) -> None:
        self.memory[(stage, key)] = value
        self.memory.move_to_end((stage, key))
        while len(self.memory) > MEMORY_ENTRIES:
            self.memory.popitem(last=False)

    def get(self, stage: str, key: str) -> tuple[dict[str, np.ndarray], dict[str, Any]] | None:
        hit = self.memory.get((stage, key))
        if hit is not None:
            self.hits[stage] = self.hits.get(stage, 0) + 1
            return {k: v.copy() for k, v in hit[0].items()}, dict(hit[1])
        if self.root is None:
            self.misses[stage] = self.misses.get(stage, 0) + 1
            return None
        p = self._path(stage, key)
        try:
            with np.load(p, allow_pickle=False) as z:
                arrays = {k: z[k] for k in z.files if k != "__meta__"}
                meta = json.loads(str(z["__meta__"])) if "__meta__" in z.files else {}
        except (OSError, ValueError, KeyError, EOFError):  # absent, or unreadable: computed again
            self.misses[stage] = self.misses.get(stage, 0) + 1
            return None
        self.hits[stage] = self.hits.get(stage, 0) + 1
        return arrays, meta

    def put(self, stage: str, key: str, arrays: dict[str, np.ndarray], meta: dict[str, Any]) -> None:
        if self.root is None:
            return
        p = self._path(stage, key)
        p.parent.mkdir(parents=True, exist_ok=True)
        buf = io.BytesIO()
        np.savez_compressed(buf, __meta__=np.array(dumps(meta).decode("utf-8")), **arrays)
        tmp = p.with_name(f".{p.name}.{os.getpid()}.tmp")
        tmp.write_bytes(buf.getvalue())
        os.replace(tmp, p)


def make_cache(cfg: dict[str, Any]) -> Cache:
    if not cfg.get("cache", True):
        return Cache(None)
    return Cache(Path(cfg["cache_dir"]).expanduser() if cfg.get("cache_dir") else default_dir())
