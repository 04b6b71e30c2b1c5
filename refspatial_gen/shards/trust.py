"""Checking a shard against its index.json before anything is read from it, once per shard per process.

Why: a byte flipped on disk can decode to plausible but wrong pixels (a zstd frame has no checksum of
its own), and a training job would learn from them silently. MCAP CRCs (checked by the scanner) catch
most damage; the sha256 that index.json records catches all of it, and before the first sample of the
shard is handed out. Hashing costs one read of the file, so it is done once per process and file
(keyed by inode, size and mtime, so a replaced file is hashed again).

`verify_against_index(path)` is called by every reader (`iter_raw`): a shard with an index.json beside
it that lists it must match the recorded size and sha256; a shard without an index (a single file
handed to `inspect`, a file list given to the stream) relies on the CRCs alone.
"""

from __future__ import annotations

import os
import threading
from pathlib import Path

from refspatial_gen.core.fsutil import sha256_file

INDEX_NAME = "index.json"
_lock = threading.Lock()
_verified: dict[tuple, str] = {}  # (realpath, inode, size, mtime_ns) -> sha256 that matched the index
_indexes: dict[tuple, dict[str, dict]] = {}  # (index path, inode, size, mtime_ns) -> {name: entry}


def _new_lock() -> None:  # a lock held by another thread at fork time would never be released in the child
    global _lock
    _lock = threading.Lock()


os.register_at_fork(after_in_child=_new_lock)


class IntegrityError(ValueError):
    """A shard that does not match its index (raised as ShardError by the readers)."""


def _key(p: Path) -> tuple:
    st = p.stat()
    return str(p.resolve()), st.st_ino, st.st_size, st.st_mtime_ns


def index_entries(index_path: Path) -> dict[str, dict]:
    """{shard name: entry} of an index.json (parsed once per process and version of the file)."""
    from refspatial_gen.shards.index import read_index

    key = _key(index_path)
    with _lock:
        hit = _indexes.get(key)
    if hit is None:
        hit = {str(s["name"]): s for s in read_index(index_path)["shards"]}
        with _lock:
            _indexes[key] = hit
    return hit


def listed_entry(path: Path) -> dict | None:
    """The index.json entry beside `path` that names it, or None when there is no index or it is unlisted.

    Raises IntegrityError when an index.json is there but cannot be read (nothing could then be trusted).
    """
    index = path.parent / INDEX_NAME
    if not index.is_file():
        return None
    try:
        return index_entries(index).get(path.name)
    except ValueError as e:
        raise IntegrityError(f"cannot check against {index}: {e}") from None


def verify_against_index(path: Path | str, entry: dict | None = None) -> bool:
    """Raise IntegrityError unless `path` has the size and sha256 its index entry records.

    `entry` defaults to the index.json beside the file. Returns False when there is nothing to check
    against (no index, or the index does not list the file), True when the file was checked (now or
    earlier in this process).
    """
    path = Path(path)
    entry = listed_entry(path) if entry is None else entry
    if entry is None:
        return False
    key = _key(path)
    want_size, want_sha = entry.get("bytes"), str(entry.get("sha256", ""))
    with _lock:
        if _verified.get(key) == want_sha:
            return True
    if key[2] != want_size:
        raise IntegrityError(
            f"size_mismatch: {key[2]} bytes on disk, index.json says {want_size} (truncated or replaced)"
        )
    digest = sha256_file(path)
    if digest != want_sha:
        raise IntegrityError(
            f"hash_mismatch: sha256 {digest[:16]}... differs from index.json's {want_sha[:16]}... "
            f"(file altered or replaced)"
        )
    with _lock:
        _verified[key] = digest
    return True


def note_verified(path: Path | str, digest: str) -> None:
    """Record a hash computed elsewhere (check_shards) so readers in this process do not hash again."""
    path = Path(path)
    with _lock:
        _verified[_key(path)] = digest


def forget() -> None:
    """Drop what this process has verified (tests; or after files were rewritten in place)."""
    with _lock:
        _verified.clear()
        _indexes.clear()
