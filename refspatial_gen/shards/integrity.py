"""Integrity of a shard directory, and salvage of a shard whose writer died.

Why: training jobs trust index.json; a shard that was truncated, altered or replaced must be caught
before a job reads it, with a message that names the file. A crash mid-write leaves `<name>.partial`
without an MCAP footer; every sample whose messages all reached the disk can still be recovered.
"""

from __future__ import annotations

import os
from pathlib import Path

from refspatial_gen.shards.index import INDEX_NAME, read_index
from refspatial_gen.shards.reader import ShardError, iter_raw
from refspatial_gen.shards.trust import note_verified
from refspatial_gen.shards.writer import CHUNK_SIZE, PARTIAL_SUFFIX, ShardInfo, _Part, sha256_file


def _problem(file: Path | str, problem: str, detail: str) -> dict:
    return {"file": str(file), "problem": problem, "detail": detail}


def check_shards(out_dir: Path | str, *, deep: bool = False) -> list[dict]:
    """Problems found in `out_dir` as dicts {file, problem, detail}; an empty list means all is well.

    Checks every shard listed in index.json exists with the recorded size and sha256; flags unfinished
    `.partial` files and shard files the index does not list. `deep=True` also reads every shard end to
    end and compares its sample and QA counts with the index (catches a file damaged before hashing).
    """
    out_dir = Path(out_dir)
    try:
        index = read_index(out_dir)
    except ValueError as e:
        return [_problem(out_dir / INDEX_NAME, "index_unreadable", str(e))]
    problems: list[dict] = []
    listed = set()
    for s in index["shards"]:
        name = str(s.get("name", ""))
        listed.add(name)
        p = out_dir / name
        if not p.is_file():
            problems.append(_problem(p, "missing", "listed in index.json but not on disk"))
            continue
        size = p.stat().st_size
        if size != s.get("bytes"):
            problems.append(_problem(p, "size_mismatch", f"{size} bytes on disk, index.json says {s.get('bytes')}"))
            continue
        digest = sha256_file(p)
        if digest != s.get("sha256"):
            problems.append(
                _problem(
                    p,
                    "hash_mismatch",
                    f"sha256 {digest[:16]}... differs from index.json's "
                    f"{str(s.get('sha256'))[:16]}... (file altered or replaced)",
                )
            )
            continue
        note_verified(p, digest)
        if deep:
            try:
                n = q = 0
                for raw in iter_raw(p):
                    n += 1
                    q += int(raw.header["qa_pairs"])
            except ShardError as e:
                problems.append(_problem(p, "unreadable", e.reason))
                continue
            if (n, q) != (s.get("samples"), s.get("qa_pairs")):
                problems.append(
                    _problem(
                        p,
                        "count_mismatch",
                        f"{n} samples / {q} QA pairs read, index.json says {s.get('samples')} / {s.get('qa_pairs')}",
                    )
                )
    problems += index_count_problems(out_dir / INDEX_NAME, index)
    for p in sorted(out_dir.glob("*" + PARTIAL_SUFFIX)):
        if p.name != INDEX_NAME + PARTIAL_SUFFIX:
            problems.append(
                _problem(
                    p,
                    "unfinished",
                    "a shard left unfinished by a crash; run `refspatial-gen shards salvage` on it or resume the run",
                )
            )
    for p in sorted(out_dir.glob("*.mcap")):
        if p.name not in listed:
            problems.append(_problem(p, "unlisted", "shard file not listed in index.json"))
    return problems


def index_count_problems(index_path: Path, index: dict) -> list[dict]:
    """The index's totals (and run stats, when present) must equal the sum of its shard rows.

    Why: the per-shard hashes say nothing about the counts written beside them; an edited count would
    otherwise pass every check and mislead `stats` and the stream's epoch plan.
    """
    rows = index["shards"]
    problems = []
    try:
        sums = {
            "shards": len(rows),
            "samples": sum(int(r["samples"]) for r in rows),
            "qa_pairs": sum(int(r["qa_pairs"]) for r in rows),
            "bytes": sum(int(r["bytes"]) for r in rows),
        }
    except (KeyError, TypeError, ValueError) as e:
        return [_problem(index_path, "index_unreadable", f"a shard row lacks a numeric count ({e})")]
    totals = index.get("totals") or {}
    for k, v in sums.items():
        if totals.get(k) != v:
            problems.append(
                _problem(index_path, "count_mismatch", f"totals.{k} is {totals.get(k)!r}, the shard rows add up to {v}")
            )
    stats = index.get("stats")
    if isinstance(stats, dict):
        for k in ("samples", "qa_pairs"):
            if k in stats and stats[k] != sums[k]:
                problems.append(
                    _problem(
                        index_path, "count_mismatch", f"stats.{k} is {stats[k]!r}, the shard rows add up to {sums[k]}"
                    )
                )
    return problems


def check_shard_file(path: Path | str) -> dict:
    """Read one shard end to end; returns {name, samples, qa_pairs, bytes, sha256} or raises ShardError."""
    path = Path(path)
    n = q = 0
    for raw in iter_raw(path):
        n += 1
        q += int(raw.header["qa_pairs"])
    return ShardInfo(path.name, n, q, path.stat().st_size, sha256_file(path)).to_dict()


def salvage_shard(partial_path: Path | str, *, out_path: Path | str | None = None, remove_partial: bool = True) -> dict:
    """Recover every complete sample of an unfinished shard into a finished one.

    The output defaults to the partial's final name (`shard-00003.mcap.partial` -> `shard-00003.mcap`;
    any other name gets `.salvaged.mcap`). Messages are copied byte for byte with their sequence
    numbers, so the result equals what the writer would have written for those samples. Returns
    {name, path, samples, qa_pairs, bytes, sha256, source}. Raises ShardError (naming the file) when
    nothing can be recovered or the file is not an MCAP shard.
    """
    src = Path(partial_path)
    if not src.is_file():
        raise ShardError(src, "no such file")
    if out_path is None:
        out_path = (
            src.with_name(src.name[: -len(PARTIAL_SUFFIX)])
            if src.name.endswith(PARTIAL_SUFFIX)
            else src.with_name(src.stem + ".salvaged.mcap")
        )
    out_path = Path(out_path)
    if out_path.exists():
        raise ShardError(src, f"{out_path} already exists; remove it or pass another output path")
    with open(src, "rb") as f:
        if f.read(8) != b"\x89MCAP0\r\n":
            raise ShardError(src, "not an MCAP file (bad magic bytes): nothing to salvage")
    part = _Part(out_path, CHUNK_SIZE, tmp_suffix=".salvage" + PARTIAL_SUFFIX)
    try:
        for raw in iter_raw(src, require_footer=False):
            part.add(list(raw.messages.items()), raw.seq, int(raw.header["qa_pairs"]))
    except BaseException:
        part.abort()
        part.tmp.unlink(missing_ok=True)
        raise
    if part.samples == 0:
        part.abort()
        part.tmp.unlink(missing_ok=True)
        raise ShardError(src, "no complete sample could be recovered")
    info = part.close().to_dict()
    if remove_partial and src.resolve() != out_path.resolve():
        os.unlink(src)
    return {**info, "path": str(out_path), "source": str(src)}
