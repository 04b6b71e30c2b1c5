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
    """Shard integrity (size and sha256 against index.json, index totals) first, then every QA pair.

    A shard with an integrity problem is reported and its samples are not read (they cannot be trusted).
    While reading, each shard's sample and QA counts are compared with its index row (`count_mismatch`),
    and a shard that fails while being read is reported (`unreadable`) instead of stopping the run."""
    from refspatial_gen.qa.verify import verify_samples
    from refspatial_gen.shards.integrity import check_shards

    problems = check_shards(Path(d))
    bad = {Path(p["file"]).name for p in problems}
    from refspatial_gen.rewrite.verify import with_rewrite_checks

    out = with_rewrite_checks(verify_samples, _iter_trusted(d, bad, problems))
    out["shard_problems"] = problems
    out["failures"] = out["failures"][:max_failures]
    return out


def _iter_trusted(d: str | Path, skip: set[str], problems: list[dict]):
    """Samples of every shard in index.json except those named in `skip`, which are never opened (a corrupt
    chunk would stop the reader before the report is written). Count and read problems go to `problems`."""
    from refspatial_gen.shards.index import read_index
    from refspatial_gen.shards.reader import ShardError, read_samples

    d = Path(d)
    for row in read_index(d)["shards"]:
        p = d / row["name"]
        if row["name"] in skip or not p.is_file():
            continue
        n = q = 0
        try:
            for s in read_samples(p):
                n += 1
                q += len(s.qa)
                yield s
        except ShardError as e:
            problems.append({"file": str(p), "problem": "unreadable", "detail": e.reason})
            continue
        if (n, q) != (row.get("samples"), row.get("qa_pairs")):
            problems.append(
                {
                    "file": str(p),
                    "problem": "count_mismatch",
                    "detail": f"{n} samples / {q} QA pairs read, index.json says "
                    f"{row.get('samples')} / {row.get('qa_pairs')}",
                }
            )
