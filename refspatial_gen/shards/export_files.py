"""What every exporter shares: file names that never collide, files written once, and the hashes to check.

Why: an export pairs text with pixels through file names. Two samples whose ids differ only in
characters a file system cannot hold (`:`, `/`, non-ASCII) must not share a file, and a file left by
an earlier export must never be picked up; a name is therefore the id itself when it is plainly safe,
else a readable part plus a stable hash of the whole id, and every file is created exclusively
(`write_new`), so a collision is an error rather than a silent overwrite or reuse.
"""

from __future__ import annotations

import hashlib
import re
from collections.abc import Callable, Iterable
from pathlib import Path

EXT = {"jpeg": "jpg", "png": "png"}
_SAFE = re.compile(r"[A-Za-z0-9][A-Za-z0-9_-]{0,99}")
_SAFE_DOT = re.compile(r"[A-Za-z0-9][A-Za-z0-9._-]{0,99}")


class ExportError(ValueError):
    """An export that cannot be made or fails its own check; the message names the file or folder."""


def sample_stem(sample_id: str, *, allow_dot: bool = True) -> str:
    """A file-system-safe, collision-free stem for a sample id (stable across runs and machines).

    Plain ASCII ids made of letters, digits, `_`, `-` (and `.` unless `allow_dot` is False: WebDataset
    keys end at the first dot) are kept as they are; any other id becomes its safe characters plus the
    first 10 hex digits of its BLAKE2b hash, so ids differing only in non-ASCII characters differ.
    """
    sid = str(sample_id)
    if (_SAFE_DOT if allow_dot else _SAFE).fullmatch(sid) and not sid.endswith("."):
        return sid
    readable = re.sub(r"[^A-Za-z0-9_-]+", "_", sid).strip("_-")[:60] or "s"
    return f"{readable}-{hashlib.blake2b(sid.encode('utf-8'), digest_size=5).hexdigest()}"


def view_name(stem: str, view: int, ext: str) -> str:
    """`<stem>_v<view>.<ext>`: unique per sample and view (the last `_v<digits>` names the view)."""
    return f"{stem}_v{view}.{ext}"


class StemRegistry:
    """Stems handed out in one export: refuses a second id with the same stem (also ignoring case,
    for case-insensitive file systems)."""

    def __init__(self) -> None:
        self._owner: dict[str, str] = {}

    def claim(self, sample_id: str, *, allow_dot: bool = True) -> str:
        stem = sample_stem(sample_id, allow_dot=allow_dot)
        owner = self._owner.setdefault(stem.casefold(), sample_id)
        if owner != sample_id:
            raise ExportError(f"samples {owner!r} and {sample_id!r} map to the same file name {stem!r}")
        return stem


def write_new(path: Path, data: bytes) -> None:
    """Create `path` with `data`; an existing file is a name collision, never overwritten or reused."""
    try:
        with open(path, "xb") as f:
            f.write(data)
    except FileExistsError:
        raise ExportError(f"{path}: already written by this export (two items map to one file name)") from None


def sha256(data: bytes) -> str:
    return hashlib.sha256(data).hexdigest()


def file_sha256(path: Path) -> str | None:
    try:
        return hashlib.sha256(Path(path).read_bytes()).hexdigest()
    except OSError:
        return None


def stored_image_hashes(raws: Iterable, on_view: Callable | None = None) -> dict[str, tuple[str, tuple[str, int]]]:
    """{image file name: (sha256 of the stored bytes, (sample_id, view))} for every view of every sample.

    The reference an export's check compares against: what the shards hold, keyed by the name the
    export must have given that view. `on_view(raw, stem, view)` is called for each view (for checks
    of other per-view files).
    """
    out: dict[str, tuple[str, tuple[str, int]]] = {}
    reg = StemRegistry()
    for raw in raws:
        h = raw.header
        stem = reg.claim(h["sample_id"])
        for v in range(int(h["views"])):
            data, fmt = raw.image_bytes(v)
            out[view_name(stem, v, EXT.get(fmt, fmt))] = (sha256(data), (h["sample_id"], v))
            if on_view is not None:
                on_view(raw, stem, v)
    return out


def check_image_refs(
    out_dir: Path, refs: Iterable[str], stored: dict[str, tuple[str, tuple[str, int]]], where: str
) -> list[str]:
    """Problems with image references: a plain view image must hold exactly the stored bytes; a marked
    copy (`..._marks<k>.png`) must exist and belong to a stored view."""
    problems: list[str] = []
    seen: set[str] = set()
    stems = {Path(k).stem for k in stored}
    for name in refs:
        if name in seen:
            continue
        seen.add(name)
        path = out_dir / name
        if "_marks" in Path(name).stem:
            base = Path(name).stem.rsplit("_marks", 1)[0]
            if not path.is_file():
                problems.append(f"{where}: marked image {name} missing")
            elif base not in stems:
                problems.append(f"{where}: marked image {name} belongs to no stored view")
            continue
        want = stored.get(name)
        got = file_sha256(path)
        if want is None:
            problems.append(f"{where}: image {name} is not a view of any sample in the shards")
        elif got is None:
            problems.append(f"{where}: image {name} missing")
        elif got != want[0]:
            problems.append(
                f"{where}: image {name} differs from the stored view {want[1]} (sha256 {got[:12]}... "
                f"!= {want[0][:12]}...)"
            )
    return problems
