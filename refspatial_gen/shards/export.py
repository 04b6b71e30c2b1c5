"""`export DIR --format refspatial|webdataset|jsonl --out X`: one entry point over the three exporters."""

from __future__ import annotations

from pathlib import Path
from typing import Iterator

from refspatial_gen.shards.format import RawSample
from refspatial_gen.shards.index import read_index
from refspatial_gen.shards.reader import iter_raw

FORMATS = ("refspatial", "webdataset", "jsonl")


def iter_dir(shard_dir: Path | str) -> Iterator[RawSample]:
    """Every sample of a shard directory, shards in index order (a truncated shard raises ShardError)."""
    d = Path(shard_dir)
    for s in read_index(d)["shards"]:
        yield from iter_raw(d / s["name"])


def export(shard_dir: Path | str, fmt: str, out: Path | str, **kw) -> dict:
    if fmt == "refspatial":
        from refspatial_gen.shards.export_refspatial import export_refspatial as fn
    elif fmt == "webdataset":
        from refspatial_gen.shards.export_webdataset import export_webdataset as fn
    elif fmt == "jsonl":
        from refspatial_gen.shards.export_jsonl import export_jsonl as fn
    else:
        raise ValueError(f"unknown export format {fmt!r} (choose from {', '.join(FORMATS)})")
    return fn(iter_dir(shard_dir), Path(out), **kw)
