"""`export DIR --format F --out X`: a table of exporters, written atomically and checked before they land.

Adding an exporter = one file with `fn(raws, out, **options) -> dict` (and optionally
`check_export(out, raws) -> [problems]` in the same module) plus one line in EXPORTERS; the CLI's
`--format` choices come from this table.

Why a temporary folder: an export pairs JSON with image files by name, so writing into a folder that
held an earlier export would pair new questions with old pixels. Every export is written into
`.<name>.partial-<pid>` beside the target, checked, and renamed into place; a non-empty target is
refused unless `overwrite=True`, which replaces it whole.
"""

from __future__ import annotations

import importlib
import inspect
import os
import shutil
from collections.abc import Callable, Iterator
from pathlib import Path

from refspatial_gen.shards.export_files import ExportError
from refspatial_gen.shards.format import RawSample
from refspatial_gen.shards.index import read_index
from refspatial_gen.shards.reader import iter_raw

EXPORTERS: dict[str, str] = {
    "refspatial": "refspatial_gen.shards.export_refspatial:export_refspatial",
    "webdataset": "refspatial_gen.shards.export_webdataset:export_webdataset",
    "jsonl": "refspatial_gen.shards.export_jsonl:export_jsonl",
    "hf": "refspatial_gen.shards.export_hf:export_hf",
    "sft": "refspatial_gen.shards.export_sft:export_sft",
    "rft": "refspatial_gen.shards.export_rft:export_rft",
    "refspatial-bench": "refspatial_gen.shards.export_refspatial_bench:export_refspatial_bench",
}
FORMATS = tuple(EXPORTERS)


class RawSource:
    """The samples of a shard directory, shards in index order; `len()` is the index's sample count.

    Iterating twice reads the shards twice (the export, then its check). Every shard is checked
    against index.json as it is opened (shards.trust); a damaged one raises ShardError naming it.
    """

    def __init__(self, shard_dir: Path | str) -> None:
        self.shard_dir = Path(shard_dir)  # exporters that need the index (splits) read it from here
        self.rows = read_index(self.shard_dir)["shards"]

    def __len__(self) -> int:
        return sum(int(s["samples"]) for s in self.rows)

    def __iter__(self) -> Iterator[RawSample]:
        for s in self.rows:
            yield from iter_raw(self.shard_dir / s["name"])


DirSamples = RawSource  # the name other exporters use for "the samples of a shard directory"


def iter_dir(shard_dir: Path | str) -> RawSource:
    """Every sample of a shard directory, shards in index order (a damaged shard raises ShardError);
    an iterable that also carries `shard_dir` (exporters that need the index's splits read it)."""
    return RawSource(shard_dir)


def exporter(fmt: str) -> Callable:
    """The export function registered for `fmt`."""
    if fmt not in EXPORTERS:
        raise ValueError(f"unknown export format {fmt!r} (choose from {', '.join(EXPORTERS)})")
    module, _, name = EXPORTERS[fmt].partition(":")
    return getattr(importlib.import_module(module), name)


def _options_for(fn: Callable, options: dict) -> dict:
    """Options the exporter accepts; an option it does not take but that was set is an error."""
    params = inspect.signature(fn).parameters
    if any(p.kind is p.VAR_KEYWORD for p in params.values()):
        return dict(options)
    unknown = sorted(k for k, v in options.items() if k not in params and v is not None)
    if unknown:
        raise ExportError(f"{fn.__name__} does not take {', '.join('--' + k.replace('_', '-') for k in unknown)}")
    return {k: v for k, v in options.items() if k in params and v is not None}


def _prepare(out: Path, overwrite: bool) -> Path:
    if out.exists() and not out.is_dir():
        raise ExportError(f"{out}: exists and is not a folder")
    if out.is_dir() and any(out.iterdir()) and not overwrite:
        raise ExportError(f"{out}: folder is not empty (an earlier export?); pass --overwrite to replace it whole")
    tmp = out.parent / f".{out.name}.partial-{os.getpid()}"
    shutil.rmtree(tmp, ignore_errors=True)
    tmp.mkdir(parents=True)
    return tmp


def _land(tmp: Path, out: Path) -> None:
    """Put the finished export in place: rename, replacing an old folder only once the new one is complete."""
    old = None
    if out.is_dir():
        old = out.parent / f".{out.name}.old-{os.getpid()}"
        os.rename(out, old)
    os.rename(tmp, out)
    if old is not None:
        shutil.rmtree(old, ignore_errors=True)


def export(
    shard_dir: Path | str, fmt: str, out: Path | str, *, overwrite: bool = False, check: bool = True, **options
) -> dict:
    """Export `shard_dir` as `fmt` into the folder `out` (created; see the module docstring).

    The exporter's own `check_export` (when its module has one) runs on the finished folder before it
    is moved into place; any problem raises ExportError and leaves `out` untouched.
    """
    fn = exporter(fmt)
    kw = _options_for(fn, options)
    src = RawSource(shard_dir)
    out = Path(out)
    here, there = src.shard_dir.resolve(), out.resolve()
    if there == here or there in here.parents or there == Path.cwd().resolve() or there.parent == there:
        raise ExportError(
            f"{out}: refusing to export into the shard folder, a folder containing it, the current "
            f"folder or the file system root (--overwrite would replace it)"
        )
    tmp = _prepare(out, overwrite)
    try:
        res = fn(src, tmp, **kw)
        checker = getattr(importlib.import_module(fn.__module__), "check_export", None)
        if check and checker is not None:
            problems = checker(tmp, src)
            if problems:
                shown = "; ".join(p.replace(str(tmp), str(out)) for p in problems[:10])
                raise ExportError(f"{out}: the export fails its own check ({len(problems)} problems): {shown}")
        _land(tmp, out)
    finally:
        shutil.rmtree(tmp, ignore_errors=True)
    return res
