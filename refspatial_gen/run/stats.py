"""Dataset statistics: counted per sample, merged per shard group and per run. Deterministic (no timings)."""

from __future__ import annotations

from collections import Counter
from typing import Any

from refspatial_gen.core.model import Sample

HEATMAP_BINS = 20


def empty_stats() -> dict[str, Any]:
    return {
        "units": 0,
        "samples": 0,
        "qa_pairs": 0,
        "by_relation": {},
        "by_family": {},
        "by_steps": {},
        "by_source": {},
        "samples_by_source": {},
        "dropped": {},
        "truth": {},
        "answer_heatmap": [[0] * HEATMAP_BINS for _ in range(HEATMAP_BINS)],
    }


def _points(answer_struct: dict) -> list:
    pts = answer_struct.get("points") or []
    if answer_struct.get("point") is not None:
        pts = list(pts) + [answer_struct["point"]]
    return [p for p in pts if isinstance(p, (list, tuple)) and len(p) == 2]


def truth_counts(sample: Sample) -> dict[str, int]:
    """What the truth checks removed or withheld in one sample, by reason.

    Convention (docs/report.md): a source records objects it removed in `frame.meta["truth"]`, the graph
    builder records objects it withheld from questions in `graph.meta["truth"]`, and the QA stage records
    rejected questions in `sample.meta["truth"]`; each is a {reason: count} dict."""
    out: Counter = Counter()
    for d in (
        [f.meta.get("truth") for f in sample.frames]
        + [g.meta.get("truth") for g in sample.graphs]
        + [sample.meta.get("truth")]
    ):
        out.update(d or {})
    return dict(out)


def add_sample(stats: dict[str, Any], sample: Sample, source_kind: str) -> None:
    stats["samples"] += 1
    for reason, n in truth_counts(sample).items():
        _inc(stats.setdefault("truth", {}), reason, int(n))
    stats["qa_pairs"] += len(sample.qa)
    _inc(stats["samples_by_source"], source_kind)
    for qa in sample.qa:
        for rel in sorted(set(qa.relations)):
            _inc(stats["by_relation"], rel)
        _inc(stats["by_family"], qa.family)
        _inc(stats["by_steps"], str(qa.steps))
        _inc(stats["by_source"], source_kind)
        for x, y in _points(qa.answer_struct):
            i = min(HEATMAP_BINS - 1, max(0, int(float(y) * HEATMAP_BINS)))
            j = min(HEATMAP_BINS - 1, max(0, int(float(x) * HEATMAP_BINS)))
            stats["answer_heatmap"][i][j] += 1


def add_drop(stats: dict[str, Any], reason: str) -> None:
    _inc(stats["dropped"], reason)


def _inc(d: dict, key: str, n: int = 1) -> None:
    d[key] = d.get(key, 0) + n


def merge(a: dict[str, Any], b: dict[str, Any]) -> dict[str, Any]:
    out = empty_stats()
    for s in (a, b):
        for k in ("units", "samples", "qa_pairs"):
            out[k] += s.get(k, 0)
        for k in ("by_relation", "by_family", "by_steps", "by_source", "samples_by_source", "dropped", "truth"):
            c = Counter(out[k])
            c.update(s.get(k, {}))
            out[k] = dict(c)
        for i, row in enumerate(s.get("answer_heatmap") or []):
            for j, v in enumerate(row):
                out["answer_heatmap"][i][j] += v
    for k in ("by_relation", "by_family", "by_steps", "by_source", "samples_by_source", "dropped", "truth"):
        out[k] = dict(sorted(out[k].items()))
    return out
