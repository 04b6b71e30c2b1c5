"""`export DIR --format F --out X`: one entry point over the exporters (one table row per format)."""

from __future__ import annotations

import importlib
from dataclasses import dataclass
from pathlib import Path
from typing import Iterator

from refspatial_gen.shards.format import RawSample
from refspatial_gen.shards.index import read_index
from refspatial_gen.shards.reader import iter_raw

# format -> "module:function"; every function is called as fn(samples, out_dir, **kw)
EXPORTERS = {
    "refspatial": "refspatial_gen.shards.export_refspatial:export_refspatial",
    "webdataset": "refspatial_gen.shards.export_webdataset:export_webdataset",
    "jsonl": "refspatial_gen.shards.export_jsonl:export_jsonl",
    "sft": "refspatial_gen.shards.export_sft:export_sft",
    "rft": "refspatial_gen.shards.export_rft:export_rft",
    "refspatial-bench": "refspatial_gen.shards.export_refspatial_bench:export_refspatial_bench",
}
FORMATS = tuple(EXPORTERS)


@dataclass(frozen=True)
class DirSamples:
    """Every sample of a shard directory, shards in index order (a truncated shard raises ShardError).

    An iterable rather than a generator so exporters that need the index (splits) can read `shard_dir`.
    """

    shard_dir: Path

    def __iter__(self) -> Iterator[RawSample]:
        for s in read_index(self.shard_dir)["shards"]:
            yield from iter_raw(self.shard_dir / s["name"])


def iter_dir(shard_dir: Path | str) -> DirSamples:
    return DirSamples(Path(shard_dir))


def export(shard_dir: Path | str, fmt: str, out: Path | str, **kw) -> dict:
    if fmt not in EXPORTERS:
        raise ValueError(f"unknown export format {fmt!r} (choose from {', '.join(FORMATS)})")
    module, name = EXPORTERS[fmt].split(":")
    fn = getattr(importlib.import_module(module), name)
    return fn(iter_dir(shard_dir), Path(out), **kw)
