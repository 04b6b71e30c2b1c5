"""Preview gallery: PNG overlays of a seeded sample of QA pairs from a shard folder, plus `index.html`.

Why: a data engineer must be able to *see* that answers land on the right object, that boxes and
free-space regions sit where the geometry says, and that questions and traces read well, before a
training job burns GPU hours on them. Each overlay draws the answer points, the target objects' 2D
boxes and projected 3D boxes, the frame's free-space regions (the answer's region highlighted), the
trace's Position key steps, and the question, answer, trace and checks as text under the image.

The choice of QA pairs is a seeded reservoir sample over the stream (shards in name order, samples
in stored order, QA pairs in order): same folder and seed -> same selection and same PNG bytes, with
at most `n` samples held in memory however large the folder is.
"""

from __future__ import annotations

import html
import json
import re
from collections.abc import Iterable, Iterator
from dataclasses import dataclass
from pathlib import Path
from typing import TypeVar

import numpy as np

from refspatial_gen.core.model import QAPair, Sample
from refspatial_gen.core.serialize import encode_png
from refspatial_gen.run.preview_checks import answer_points, point_checks, question_frames
from refspatial_gen.run.preview_render import render_preview

__all__ = [
    "Pick",
    "answer_points",
    "iter_shard_samples",
    "pick_from_shards",
    "point_checks",
    "preview_dir",
    "question_frames",
    "render_gallery",
    "render_preview",
    "reservoir",
    "reservoir_pick",
    "shard_paths",
    "write_gallery",
]

SHARD_SUFFIX = ".mcap"
T = TypeVar("T")


# ---------------------------------------------------------------------------------------------- sampling
@dataclass(frozen=True)
class Pick:
    """One chosen QA pair: its position in the stream and where it came from."""

    order: int  # index of the QA pair in the stream (shards by name, samples in order, QA in order)
    source: str  # shard file name (or "" for in-memory samples)
    sample_id: str
    qa_index: int
    qa_id: str


def reservoir(items: Iterable[T], n: int, seed: int) -> list[tuple[int, T]]:
    """Algorithm R with a seeded Generator: `n` items uniformly from a stream of unknown length.

    Returns (stream position, item) sorted by position; holds at most `n` items at any time.
    """
    if n <= 0:
        return []
    rng = np.random.default_rng(seed)
    chosen: list[tuple[int, T]] = []
    for t, item in enumerate(items):
        if len(chosen) < n:
            chosen.append((t, item))
        else:
            j = int(rng.integers(0, t + 1))
            if j < n:
                chosen[j] = (t, item)
    return sorted(chosen, key=lambda ti: ti[0])


def reservoir_pick(stream: Iterable[tuple[str, Sample]], n: int, seed: int) -> list[tuple[Pick, Sample]]:
    """`n` QA pairs from `(source name, Sample)` pairs, every QA pair equally likely; in stream order.

    Only samples with a chosen QA pair are kept, so memory does not grow with the stream.
    """
    items = ((src, s, qi) for src, s in stream for qi in range(len(s.qa)))
    return [(Pick(t, src, s.sample_id, qi, s.qa[qi].qa_id), s) for t, (src, s, qi) in reservoir(items, n, seed)]


def _safe(name: str) -> str:
    return re.sub(r"[^A-Za-z0-9._-]+", "_", name)[:80]


def write_gallery(
    stream: Iterable[tuple[str, Sample]], out: Path, n: int = 24, seed: int = 0, title: str = "refspatial-gen preview"
) -> Path:
    """Render a seeded sample of `n` QA pairs from `(source_name, Sample)` pairs into `out`; returns index.html."""
    return render_gallery(reservoir_pick(stream, n, seed), out, n, seed, title)


def render_gallery(picks: list[tuple[Pick, Sample]], out: Path, n: int, seed: int, title: str) -> Path:
    """One PNG per picked QA pair, `preview.json` listing them, and `index.html` linking them."""
    out = Path(out)
    out.mkdir(parents=True, exist_ok=True)
    for old in out.glob("qa_*.png"):  # a re-run must not leave images of another selection
        old.unlink()
    cards, listing = [], []
    for k, (pick, sample) in enumerate(picks):
        qa = sample.qa[pick.qa_index]
        if qa.qa_id != pick.qa_id:
            raise ValueError(
                f"{pick.source}: sample {pick.sample_id} QA {pick.qa_index} is {qa.qa_id}, expected {pick.qa_id}"
            )
        name = f"qa_{k:03d}_{_safe(pick.qa_id)}.png"
        (out / name).write_bytes(encode_png(render_preview(sample, pick.qa_index)))
        checks = point_checks(sample, qa)
        listing.append(
            {
                "file": name,
                "order": pick.order,
                "source": pick.source,
                "sample_id": pick.sample_id,
                "qa_index": pick.qa_index,
                "qa_id": pick.qa_id,
                "family": qa.family,
                "steps": qa.steps,
                "checks": [{"text": t, "ok": ok} for t, ok in checks],
            }
        )
        cards.append(_card(name, pick, qa, listing[-1]["checks"]))
    (out / "preview.json").write_text(
        json.dumps({"seed": seed, "n": n, "picked": listing}, indent=1, sort_keys=True, ensure_ascii=False) + "\n",
        encoding="utf-8",
    )
    index = out / "index.html"
    index.write_text(_page(title, seed, cards), encoding="utf-8")
    return index


def _card(name: str, pick: Pick, qa: QAPair, checks: list[dict]) -> str:
    e = html.escape
    bad = not all(c["ok"] for c in checks)
    flag = '<span class="bad">point check failed</span>' if bad else ""
    src = f" · {e(pick.source)}" if pick.source else ""
    return (
        f'<figure class="card"><a href="{e(name)}"><img src="{e(name)}" loading="lazy" alt="{e(qa.qa_id)}"></a>'
        f'<figcaption><div class="meta">{e(qa.family)} · {qa.steps} step{"s" if qa.steps != 1 else ""}'
        f" · {e(', '.join(qa.relations) or '-')} {flag}</div>"
        f'<div class="q">{e(qa.question)}</div><div class="a">{e(qa.answer)}</div>'
        f'<div class="id">{e(pick.sample_id)} · {e(pick.qa_id)}{src}</div></figcaption></figure>'
    )


_CSS = """
body{font-family:system-ui,-apple-system,"DejaVu Sans",sans-serif;margin:0;background:#f4f5f7;color:#1d1f23}
header{background:#1d1f23;color:#fff;padding:14px 24px}header h1{margin:0;font-size:20px}
header p{margin:4px 0 0;color:#bbb;font-size:13px}
main{display:grid;grid-template-columns:repeat(auto-fill,minmax(440px,1fr));gap:16px;padding:16px 24px}
.card{margin:0;background:#fff;border-radius:6px;box-shadow:0 1px 3px rgba(0,0,0,.15);overflow:hidden}
.card img{display:block;width:100%;height:auto}.card figcaption{padding:8px 12px 12px;font-size:13px}
.meta{color:#555;font-size:12px}.q{margin-top:6px}.a{margin-top:4px;font-weight:600;color:#b3261e}
.id{margin-top:6px;color:#888;font-size:11px;word-break:break-all}.bad{color:#fff;background:#b3261e;padding:0 4px}
"""


def _page(title: str, seed: int, cards: list[str]) -> str:
    e = html.escape
    body = "\n".join(cards) if cards else "<p>No QA pairs found.</p>"
    return (
        f'<!doctype html>\n<html lang="en"><head><meta charset="utf-8"><title>{e(title)}</title>'
        f"<style>{_CSS}</style></head><body>\n<header><h1>{e(title)}</h1>"
        f"<p>{len(cards)} QA pairs, seeded sample (seed {seed}). Click an image for full size.</p></header>\n"
        f"<main>\n{body}\n</main></body></html>\n"
    )


# ---------------------------------------------------------------------------------------------- shards
def shard_paths(folder: Path) -> list[Path]:
    """Complete shard files under `folder`, in a stable order (relative path)."""
    folder = Path(folder)
    if folder.is_file():
        return [folder]
    return sorted(
        (p for p in folder.rglob(f"*{SHARD_SUFFIX}") if p.is_file()), key=lambda p: p.relative_to(folder).as_posix()
    )


def _shard_names(folder: Path) -> list[tuple[str, Path]]:
    folder = Path(folder)
    return [(p.name if folder.is_file() else p.relative_to(folder).as_posix(), p) for p in shard_paths(folder)]


def iter_shard_samples(folder: Path) -> Iterator[tuple[str, Sample]]:
    """(shard name, Sample) over every shard under `folder`, fully decoded, via the shard reader."""
    from refspatial_gen.shards.reader import read_samples

    for name, p in _shard_names(folder):
        for s in read_samples(p):
            yield name, s


def pick_from_shards(folder: Path, n: int, seed: int) -> list[tuple[Pick, Sample]]:
    """The same picks as `reservoir_pick(iter_shard_samples(folder), n, seed)`, but cheap on big folders:
    the sampling pass reads only metadata (no pixels decoded), then only the picked samples are decoded."""
    from refspatial_gen.shards.reader import ShardError, iter_raw, read_sample_meta

    shards = _shard_names(folder)
    items = (
        (name, p, m["seq"], m["sample_id"], qi, q["qa_id"])
        for name, p in shards
        for m in read_sample_meta(p)
        for qi, q in enumerate(m["qa"])
    )
    chosen = reservoir(items, n, seed)
    wanted: dict[Path, set[int]] = {}
    for _, (_, p, seq, *_rest) in chosen:
        wanted.setdefault(p, set()).add(seq)
    loaded: dict[tuple[Path, int], Sample] = {}
    for _, p in shards:
        if p not in wanted:
            continue
        for raw in iter_raw(p):
            if raw.seq in wanted[p]:
                try:
                    loaded[(p, raw.seq)] = raw.decode()
                except (ValueError, KeyError, TypeError) as e:
                    raise ShardError(p, f"sample with sequence {raw.seq} does not decode: {e}") from None
    return [(Pick(t, name, sid, qi, qa_id), loaded[(p, seq)]) for t, (name, p, seq, sid, qi, qa_id) in chosen]


def preview_dir(folder: Path, out: Path, n: int = 24, seed: int = 0) -> Path:
    """`refspatial-gen preview`: gallery of `n` seeded QA pairs from the shards under `folder`."""
    if not shard_paths(folder):
        raise FileNotFoundError(f"no {SHARD_SUFFIX} shards under {folder}")
    return render_gallery(
        pick_from_shards(folder, n, seed), out, n, seed, title=f"refspatial-gen preview: {Path(folder).resolve().name}"
    )
