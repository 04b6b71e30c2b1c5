"""The rewriting stage: QA pairs -> model rewrites -> checked -> kept, or the original kept and counted.

For each selected pair: gather its facts, build the chat request (model, messages, sampling, a seed from
the qa_id), take the reply from the cache or the server (bounded concurrency, retries in the client,
JSON format falling back json_schema -> json_object -> none when the server refuses one), then judge it
in the pairs' order (so results do not depend on timing). A kept rewrite replaces the question; its
original and the re-attached suffix are recorded in `sample.meta["rewrite"]["pairs"]` for `verify`.
Every pair not rewritten is counted by reason in `sample.meta["truth"]` as `rewrite_<reason>` (the run
report's truth table, docs/report.md); `sample.meta["rewrite"]` also holds the accepted count.
"""

from __future__ import annotations

import dataclasses
import hashlib
import threading
from collections import Counter
from concurrent.futures import ThreadPoolExecutor
from pathlib import Path
from typing import Any

from refspatial_gen.core.model import QAPair, Sample
from refspatial_gen.rewrite.cache import ReplyCache
from refspatial_gen.rewrite.check import answer_matches, assemble, body_reason
from refspatial_gen.rewrite.client import FORMATS, ChatClient, FormatUnsupported, ServerError, parse_reply, reply_schema
from refspatial_gen.rewrite.config import RewriteConfig
from refspatial_gen.rewrite.facts import Facts, qa_facts

DEFAULT_CACHE = Path.home() / ".cache" / "refspatial-gen" / "rewrite"


def _unit_hash(text: str) -> int:
    return int.from_bytes(hashlib.sha256(text.encode()).digest()[:4], "big")


class Rewriter:
    """Rewrites the QA pairs of samples in place. One per process; the thread pool is reused."""

    def __init__(self, cfg: RewriteConfig, cache_dir: str | Path, client: ChatClient | None = None) -> None:
        self.cfg = cfg
        self.cache = ReplyCache(cache_dir)
        self.client = client or ChatClient(
            cfg.base_url(),
            api_key=cfg.api_key(),
            timeout=cfg.timeout,
            retries=cfg.retries,
            backoff=cfg.backoff,
            backoff_max=cfg.backoff_max,
        )
        self.modes = FORMATS if cfg.response_format == "auto" else (cfg.response_format,)
        self._mode = 0
        self._lock = threading.Lock()
        self._pool = ThreadPoolExecutor(max_workers=cfg.concurrency, thread_name_prefix="rewrite")
        self.counts: Counter = Counter()

    def close(self) -> None:
        self._pool.shutdown(wait=True)

    # ------------------------------------------------------------------ requests
    def selected(self, qa: QAPair) -> bool:
        if not self.cfg.wants(qa.family):
            return False
        return self.cfg.share >= 1.0 or _unit_hash(f"share:{qa.qa_id}") < self.cfg.share * 2**32

    def request(self, f: Facts) -> dict[str, Any]:
        """The request body: everything that decides the reply (and so the cache key)."""
        return {
            "model": self.cfg.model,
            "messages": self.cfg.prompts.messages(f),
            **self.cfg.sampling,
            "seed": _unit_hash(f"{self.cfg.seed}:{f.qa_id}") & 0x7FFFFFFF,
        }

    def reply(self, body: dict[str, Any]) -> str:
        """Cached reply, else the server's (then cached). Raises ServerError."""
        for m in self.modes:
            hit = self.cache.get(body, m)
            if hit is not None:
                self.cache.hits += 1
                return hit
        self.cache.misses += 1
        while True:
            with self._lock:
                k = self._mode
            if k >= len(self.modes):
                raise ServerError("format_unsupported", "the server refused every response format")
            try:
                text = self.client.complete(body, self.modes[k], reply_schema(self.cfg.prompts.ask_answer))
            except FormatUnsupported:
                with self._lock:
                    if self._mode == k:
                        self._mode = k + 1
                continue
            self.cache.put(body, self.modes[k], text)
            return text

    def _reply_or_error(self, body: dict[str, Any]) -> str | ServerError:
        try:
            return self.reply(body)
        except ServerError as e:
            return e

    # ------------------------------------------------------------------ judging
    def judge(self, f: Facts, reply: str | ServerError) -> tuple[str | None, str | None]:
        """(reason, new question): reason None means the rewrite is kept."""
        if isinstance(reply, ServerError):
            return "server_error", None
        parsed = parse_reply(reply)
        if parsed is None:
            return "bad_json", None
        q, a = parsed
        if (a is not None or self.cfg.prompts.ask_answer) and not answer_matches(f.answer, a):
            return "answer_changed", None
        new_q = assemble(q, f.suffix, f.body)
        new_body = new_q[: len(new_q) - len(f.suffix)].rstrip() if f.suffix else new_q
        reason = body_reason(f.body, new_body, f.phrases, f.words, f.vocab, f.answer, self.cfg.limits, f.form)
        return reason, (new_q if reason is None else None)

    def rewrite_samples(self, samples: list[Sample]) -> Counter:
        """Rewrite every selected pair of `samples` in place; returns this call's counts by outcome."""
        jobs: list[tuple[Sample, QAPair, Facts | None]] = []
        for s in samples:
            done = (s.meta.get("rewrite") or {}).get("pairs") or {}
            for qa in s.qa:
                if qa.qa_id not in done and self.selected(qa):
                    jobs.append((s, qa, qa_facts(qa, s.graphs)))
        futures = [None if f is None else self._pool.submit(self._reply_or_error, self.request(f)) for _, _, f in jobs]
        counts: Counter = Counter()
        for (s, qa, f), fut in zip(jobs, futures):
            if f is None or fut is None:
                reason, new_q = "no_suffix", None
            else:
                reason, new_q = self.judge(f, fut.result())
            _record(s, qa, f, reason, new_q, self.cfg)
            counts["accepted" if reason is None else reason] += 1
        self.counts.update(counts)
        return counts


def _record(s: Sample, qa: QAPair, f: Facts | None, reason: str | None, new_q: str | None, cfg: RewriteConfig) -> None:
    meta = s.meta.setdefault(
        "rewrite", {"model": cfg.model, "accepted": 0, "pairs": {}, "limits": dataclasses.asdict(cfg.limits)}
    )
    if reason is None and f is not None and new_q is not None:
        meta["pairs"][qa.qa_id] = {"original": qa.question, "suffix": f.suffix}
        meta["accepted"] += 1
        qa.question = new_q
        return
    truth = s.meta.setdefault("truth", {})
    key = f"rewrite_{reason}"
    truth[key] = truth.get(key, 0) + 1


_REWRITERS: dict[tuple, Rewriter] = {}


def rewrite_sample(cfg: RewriteConfig, sample: Sample, out_dir: str | Path | None = None) -> Counter:
    """The pipeline's hook: rewrite one sample with this process's Rewriter for `cfg`."""
    cache = Path(cfg.cache) if cfg.cache else (Path(out_dir) / "rewrite_cache" if out_dir else DEFAULT_CACHE)
    key = (id(cfg), str(cache))
    rw = _REWRITERS.get(key)
    if rw is None:
        rw = _REWRITERS[key] = Rewriter(cfg, cache)
    return rw.rewrite_samples([sample])
