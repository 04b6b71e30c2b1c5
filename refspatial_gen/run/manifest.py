"""What an input folder holds, by content: relative paths, sizes and sha256, summed into one digest.

Why: the run's fingerprint must change when the input changes, not only when its folder name does (a
different dataset in a folder of the same name must not resume into the old shards). Hashing every byte
costs about one read of the input (sha256 runs at ~1-2 GB/s per core; files are hashed on a few threads),
so it is done once: the per-file hashes are stored with each file's size and mtime in
`<out>/_parts/input-<n>.json`, and a resume re-hashes only the files whose size or mtime changed (a
resume of an unchanged 100 GB input costs one `stat` per file). The digest covers relative paths, sizes
and contents only, so a copy of the same data elsewhere (or with new mtimes) gives the same digest.
"""

from __future__ import annotations

import hashlib
import json
import os
from concurrent.futures import ThreadPoolExecutor
from pathlib import Path
from typing import Any

from refspatial_gen.core.errors import InputError
from refspatial_gen.core.fsutil import atomic_write_bytes, sha256_file

HASH_THREADS = 4


def list_files(root: Path) -> list[tuple[str, int, int]]:
    """(relative posix path, size, mtime_ns) of every regular file under `root`, sorted; symlinked folders
    are followed once (a loop is not walked twice). A single file as root lists itself as '.'."""
    root = Path(root)
    try:
        st = root.stat()
    except OSError as e:
        raise InputError(str(root), f"cannot read: {e.strerror or e}") from None
    if not root.is_dir():
        return [(".", st.st_size, st.st_mtime_ns)]
    out: list[tuple[str, int, int]] = []
    seen: set[tuple[int, int]] = set()

    def onerror(e: OSError) -> None:
        raise InputError(str(e.filename or root), f"cannot read: {e.strerror or e}")

    for dirpath, dirnames, filenames in os.walk(root, followlinks=True, onerror=onerror):
        dst = os.stat(dirpath)
        if (dst.st_dev, dst.st_ino) in seen:
            dirnames[:] = []
            continue
        seen.add((dst.st_dev, dst.st_ino))
        dirnames.sort()
        for name in sorted(filenames):
            p = os.path.join(dirpath, name)
            try:
                fst = os.stat(p)
            except OSError:
                continue  # a dangling symlink is not part of the data
            if os.path.isfile(p):
                out.append((Path(p).relative_to(root).as_posix(), fst.st_size, fst.st_mtime_ns))
    out.sort()
    return out


def _hash(root: Path, rel: str) -> str:
    try:
        return sha256_file(root if rel == "." else root / rel)
    except OSError as e:
        raise InputError(str(root / rel), f"cannot read: {e.strerror or e}") from None


def input_manifest(root: str | Path, cache: Path | None = None) -> dict[str, Any]:
    """{"files", "bytes", "digest"} of the input; per-file hashes reused from `cache` when size and mtime match."""
    root = Path(root).resolve()
    files = list_files(root)
    known: dict[str, tuple[int, int, str]] = {}
    if cache is not None and cache.is_file():
        try:
            old = json.loads(cache.read_bytes())
            if old.get("root") == str(root):
                known = {r: (s, m, h) for r, s, m, h in old.get("entries", [])}
        except (OSError, ValueError, TypeError):
            known = {}
    todo = [rel for rel, size, mtime in files if known.get(rel, (None, None))[:2] != (size, mtime)]
    with ThreadPoolExecutor(max_workers=HASH_THREADS) as pool:
        fresh = dict(zip(todo, pool.map(lambda r: _hash(root, r), todo)))
    entries = [[rel, size, mtime, fresh[rel] if rel in fresh else known[rel][2]] for rel, size, mtime in files]
    h = hashlib.sha256()
    for rel, size, _, digest in entries:
        h.update(f"{rel}\0{size}\0{digest}\n".encode("utf-8", "surrogateescape"))
    if cache is not None and (todo or len(known) != len(entries)):
        atomic_write_bytes(cache, json.dumps({"root": str(root), "entries": entries}).encode())
    return {
        "files": len(entries),
        "bytes": sum(e[1] for e in entries),
        "digest": h.hexdigest(),
        "hashed_now": len(todo),
    }


def bench_manifest(work: Path, total_mb: int = 256, files: int = 64) -> dict[str, Any]:
    """`make bench`: hashing throughput of a first run, and the cost of a resume (size/mtime check only)."""
    import time

    root = Path(work) / "manifest-input"
    root.mkdir(parents=True, exist_ok=True)
    chunk = os.urandom(1 << 20)
    for i in range(files):
        with open(root / f"f{i:04d}.bin", "wb") as f:
            for _ in range(max(1, total_mb // files)):
                f.write(chunk)
    cache = Path(work) / "manifest-cache.json"
    t0 = time.perf_counter()
    first = input_manifest(root, cache)
    t1 = time.perf_counter()
    again = input_manifest(root, cache)
    t2 = time.perf_counter()
    assert again["digest"] == first["digest"] and again["hashed_now"] == 0
    mb = first["bytes"] / 1e6
    return {
        "input_mb": round(mb, 1),
        "files": first["files"],
        "first_run_s": round(t1 - t0, 3),
        "hash_mb_per_s": round(mb / (t1 - t0), 1),
        "resume_check_s": round(t2 - t1, 4),
    }
