"""On-disk cache of model replies, keyed by everything that decides a reply.

Why: a rerun or a resumed run must send no request twice and produce the same bytes, and a dataset's
rewrites must be reproducible on a machine without the server. The key is the sha256 of the canonical JSON
of (model id, messages, sampling parameters, seed, response format); the entry holds the reply text and
the request it answers (so a shipped cache documents itself). One file per entry, written atomically, so
several worker processes can share a cache folder. Server failures are never cached.
"""

from __future__ import annotations

import hashlib
import json
import os
from pathlib import Path
from typing import Any

from refspatial_gen.core.serialize import dumps


def request_key(body: dict[str, Any], mode: str) -> str:
    return hashlib.sha256(dumps({"request": body, "format": mode})).hexdigest()


class ReplyCache:
    """`get(body, mode)` -> reply text or None; `put(body, mode, text)`."""

    def __init__(self, folder: str | Path) -> None:
        self.folder = Path(folder)
        self.hits = 0
        self.misses = 0

    def _path(self, key: str) -> Path:
        return self.folder / key[:2] / f"{key}.json"

    def get(self, body: dict[str, Any], mode: str) -> str | None:
        p = self._path(request_key(body, mode))
        try:
            entry = json.loads(p.read_bytes())
        except (OSError, ValueError):
            return None
        text = entry.get("reply") if isinstance(entry, dict) else None
        return text if isinstance(text, str) else None

    def put(self, body: dict[str, Any], mode: str, text: str) -> None:
        key = request_key(body, mode)
        p = self._path(key)
        p.parent.mkdir(parents=True, exist_ok=True)
        tmp = p.with_name(f"{p.name}.{os.getpid()}.tmp")
        tmp.write_bytes(dumps({"request": body, "format": mode, "reply": text}) + b"\n")
        os.replace(tmp, p)
