"""`refspatial-gen rewrite DIR --out DIR2`: rewrite a finished dataset later, or on another machine.

Shard by shard: read the samples, rewrite them (the shard's pairs in flight together, up to the config's
concurrency), write the shard under the same name in DIR2, then record it in `DIR2/_rewrite_parts/`. A
killed run resumes: recorded shards whose file still matches its sha256 are kept, the others are redone
(their replies come from the cache, so nothing is asked twice). `index.json` (the source's run identity
plus the rewrite model, with recomputed stats) is written last.
"""

from __future__ import annotations

import json
from collections import Counter
from collections.abc import Callable
from pathlib import Path
from typing import Any

from refspatial_gen.core.fsutil import atomic_write_bytes, sha256_file
from refspatial_gen.core.serialize import dumps
from refspatial_gen.rewrite.config import RewriteConfig
from refspatial_gen.rewrite.stage import Rewriter

PARTS = "_rewrite_parts"


def _done(out: Path, row: dict[str, Any], model: str) -> dict[str, Any] | None:
    """The shard's record if it was rewritten from this very source shard by this model and is intact."""
    p = out / PARTS / f"{row['name']}.json"
    try:
        rec = json.loads(p.read_bytes())
    except (OSError, ValueError):
        return None
    if rec.get("source_sha256") != row.get("sha256") or rec.get("model") != model:
        return None
    for s in rec.get("shards", []):
        f = out / s["name"]
        if not f.is_file() or f.stat().st_size != s["bytes"] or sha256_file(f) != s["sha256"]:
            return None
    return rec


def rewrite_dir(
    src: str | Path,
    out: str | Path,
    cfg: RewriteConfig,
    cache_dir: str | Path | None = None,
    rewriter: Rewriter | None = None,
    progress: Callable[[str, Counter], None] | None = None,
) -> dict:
    """Rewrite every shard of `src` into `out`; returns {"index", "stats", "counts"}."""
    from refspatial_gen.shards.index import read_index, write_index

    src, out = Path(src), Path(out)
    if src.resolve() == out.resolve():
        raise ValueError("--out must differ from the source folder")
    index = read_index(src)
    out.mkdir(parents=True, exist_ok=True)
    (out / PARTS).mkdir(exist_ok=True)
    cache = Path(cache_dir) if cache_dir else (Path(cfg.cache) if cfg.cache else out / "rewrite_cache")
    rw = rewriter or Rewriter(cfg, cache)
    counts: Counter = Counter()
    infos: list[dict[str, Any]] = []
    try:
        for row in index["shards"]:
            rec = _done(out, row, cfg.model)
            if rec is None:
                rec = {
                    **_rewrite_shard(src / row["name"], out / row["name"], rw),
                    "source_sha256": row.get("sha256"),
                    "model": cfg.model,
                }
                atomic_write_bytes(out / PARTS / f"{row['name']}.json", dumps(rec))
            counts.update(rec["counts"])
            infos += [{**s, **({"group": row["group"]} if "group" in row else {})} for s in rec["shards"]]
            if progress is not None:
                progress(row["name"], Counter(rec["counts"]))
    finally:
        if rewriter is None:
            rw.close()
    # the same pairs as the source: its stats hold, plus the rewrite's rejections in the truth counts
    stats = json.loads(json.dumps(index.get("stats") or {}))
    truth = stats.setdefault("truth", {})
    for reason, n in counts.items():
        if reason != "accepted":
            truth[f"rewrite_{reason}"] = truth.get(f"rewrite_{reason}", 0) + n
    stats["truth"] = dict(sorted(truth.items()))
    run_info = {k: v for k, v in index.items() if k not in ("schema_version", "kind", "shards", "totals", "stats")}
    run_info["rewrite"] = {"model": cfg.model, "source_index_sha256": sha256_file(src / "index.json")}
    new_index = write_index(out, infos, {**run_info, "stats": stats})
    return {"index": new_index, "stats": stats, "counts": dict(sorted(counts.items()))}


def _rewrite_shard(path: Path, out_path: Path, rw: Rewriter) -> dict[str, Any]:
    """Rewrite one shard's questions; every other message (pixels included) is copied byte for byte."""
    from refspatial_gen.core.model import QAPair, Sample, SceneGraph
    from refspatial_gen.shards.reader import iter_raw
    from refspatial_gen.shards.writer import CHUNK_SIZE, _Part

    raws = list(iter_raw(path))
    samples = []
    for raw in raws:
        h = raw.header
        samples.append(
            Sample(
                sample_id=h["sample_id"],
                frames=[],
                unit_key=h["unit_key"],
                meta=dict(h["meta"]),
                graphs=[SceneGraph.from_json(g) for g in raw.graphs_json()],
                qa=[QAPair.from_json(q) for q in raw.qa_json()],
            )
        )
    counts = rw.rewrite_samples(samples)
    part = _Part(out_path, CHUNK_SIZE)
    try:
        for raw, s in zip(raws, samples):
            msgs = dict(raw.messages)
            msgs["/sample"] = dumps({**raw.header, "meta": s.meta})
            msgs["/qa"] = dumps({"qa": [q.to_json() for q in s.qa]})
            part.add(list(msgs.items()), raw.seq, len(s.qa))
    except BaseException:
        part.abort()
        part.tmp.unlink(missing_ok=True)
        raise
    return {"source": path.name, "shards": [part.close().to_dict()], "counts": dict(counts)}


def accepted_share(counts: dict[str, int]) -> float:
    n = sum(counts.values())
    return counts.get("accepted", 0) / n if n else 0.0
