"""Verify a finished shard folder: integrity against index.json first, then every QA pair."""

from __future__ import annotations

from pathlib import Path


def iter_dir_samples(d: str | Path):
    """Every sample of every shard listed in DIR/index.json, in index order."""
    from refspatial_gen.shards.index import read_index
    from refspatial_gen.shards.reader import read_samples

    d = Path(d)
    index = read_index(d)
    for row in index["shards"]:
        yield from read_samples(d / row["name"])


def verify_dir(d: str | Path, max_failures: int = 1000) -> dict:
    """Shard integrity (size and sha256 against index.json) first, then every QA pair.

    A shard with an integrity problem is reported and its samples are not read (they cannot be trusted)."""
    from refspatial_gen.qa.verify import verify_samples
    from refspatial_gen.shards.integrity import check_shards

    problems = check_shards(Path(d))
    bad = {Path(p["file"]).name for p in problems}
    from refspatial_gen.rewrite.verify import with_rewrite_checks

    out = with_rewrite_checks(verify_samples, _iter_trusted(d, bad))
    out["shard_problems"] = problems
    out["failures"] = out["failures"][:max_failures]
    return out


def _iter_trusted(d: str | Path, skip: set[str]):
    """Samples of every shard in index.json except those named in `skip`, which are never opened (a corrupt
    chunk would stop the reader before the report is written)."""
    from refspatial_gen.shards.index import read_index
    from refspatial_gen.shards.reader import read_samples

    d = Path(d)
    for row in read_index(d)["shards"]:
        if row["name"] not in skip and (d / row["name"]).is_file():
            yield from read_samples(d / row["name"])
