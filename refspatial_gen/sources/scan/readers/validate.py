"""Value checks for scan readers: every number, matrix and file name read from a scan is checked here.

Why: a malformed scan file must drop the view it belongs to with a named reason (DropUnit), never reach
numpy or the geometry as a string, a ragged list or NaN and fail there with a traceback. A file that
lists the views themselves (ScanNet's scene.json, a TUM rgb.txt) and cannot be read prevents planning:
`InputError(path, message)`, exit 2.
"""

from __future__ import annotations

import math
from pathlib import Path, PurePosixPath
from typing import Any

import numpy as np

from refspatial_gen.core.errors import DropUnit, InputError
from refspatial_gen.core.jsonfile import loads_checked


def short(v: Any, limit: int = 40) -> str:
    r = repr(v)
    return r if len(r) <= limit else r[: limit - 3] + "..."


def number(v: Any, what: str, reason: str = "annotation_invalid") -> float:
    if isinstance(v, bool) or not isinstance(v, (int, float)) or not math.isfinite(v):
        raise DropUnit(reason, f"{what} must be a finite number, got {short(v)}")
    return float(v)


def positive_int(v: Any, what: str, reason: str = "annotation_invalid") -> int:
    if (
        isinstance(v, bool)
        or not isinstance(v, (int, float))
        or not math.isfinite(v)
        or v != int(v)
        or v <= 0
        or v > 1_000_000
    ):
        raise DropUnit(reason, f"{what} must be a positive integer, got {short(v)}")
    return int(v)


def matrix(v: Any, shapes: tuple[tuple[int, ...], ...], what: str, reason: str = "annotation_invalid") -> np.ndarray:
    """A nested list of finite numbers of one of `shapes` (a flat list of the same size is accepted too)."""
    try:
        a = np.asarray(v, dtype=object)
    except (ValueError, TypeError):
        a = None
    if a is None:
        raise DropUnit(reason, f"{what} must be a matrix, got {short(v)}")
    flat = a.reshape(-1).tolist() if a.ndim else []
    for s in shapes:
        if a.shape == s or (a.ndim == 1 and a.size == int(np.prod(s))):
            return np.array([number(x, what, reason) for x in flat], float).reshape(s)
    raise DropUnit(reason, f"{what} must be {' or '.join('x'.join(map(str, s)) for s in shapes)}, got shape {a.shape}")


def pose(v: Any, what: str) -> np.ndarray:
    """A 4x4 (or 3x4) camera pose of finite numbers -> 4x4."""
    A = matrix(v, ((4, 4), (3, 4)), what, "pose_invalid")
    if A.shape == (3, 4):
        A = np.vstack([A, [0, 0, 0, 1.0]])
    return A


def file_in(root: Path, v: Any, what: str) -> Path:
    """A file named inside a scan: a relative path that stays inside the scan folder."""
    if not isinstance(v, str) or not v or "\0" in v:
        raise DropUnit("annotation_invalid", f"{what} must be a file name, got {short(v)}")
    p = PurePosixPath(v.replace("\\", "/"))
    if p.is_absolute() or ".." in p.parts:
        raise DropUnit("path_outside_input", f"{what} {v!r} leaves the input folder")
    return Path(root) / p


def mapping(v: Any, what: str, reason: str = "annotation_invalid") -> dict:
    if not isinstance(v, dict):
        raise DropUnit(reason, f"{what} must be a mapping, got {type(v).__name__}")
    return v


def listing(v: Any, what: str, reason: str = "annotation_invalid") -> list:
    if not isinstance(v, list):
        raise DropUnit(reason, f"{what} must be a list, got {type(v).__name__}")
    return v


def index_json(path: Path) -> Any:
    """A file that lists the views (it must be readable for anything to be planned): InputError if not."""
    try:
        raw = Path(path).read_bytes()
    except OSError as e:
        raise InputError(str(path), f"cannot read: {e.strerror or e}") from None
    if not raw.strip():
        raise InputError(str(path), "file is empty")
    return loads_checked(raw, path)


def view_list(meta: Any, path: Path, key: str = "frames") -> list:
    """The view list of an index file: a JSON object whose `key` is a list (InputError otherwise)."""
    if not isinstance(meta, dict):
        raise InputError(str(path), f"must be a JSON object, got {type(meta).__name__}")
    frames = meta.get(key, [])
    if not isinstance(frames, list):
        raise InputError(str(path), f"`{key}` must be a list of frames, got {type(frames).__name__}")
    return frames
