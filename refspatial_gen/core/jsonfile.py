"""JSON from a dataset's bytes, every way it can be broken named in one `path: what is wrong` InputError.

Why shared: the image annotations and the scan index files are both user inputs; a truncated, non-UTF-8 or
absurdly nested file must read the same in both (no traceback ever reaches a user)."""

from __future__ import annotations

import json
from pathlib import Path
from typing import Any

from refspatial_gen.core.errors import InputError


def loads_checked(raw: bytes, path: str | Path) -> Any:
    """json.loads(raw), or InputError(path, reason) with line/column and a truncation hint."""
    try:
        return json.loads(raw)
    except UnicodeDecodeError:
        raise InputError(str(path), "not UTF-8 JSON text") from None
    except json.JSONDecodeError as e:
        hint = " (truncated?)" if e.pos >= len(raw.rstrip()) - 1 else ""
        raise InputError(str(path), f"not valid JSON: {e.msg} at line {e.lineno}, column {e.colno}{hint}") from None
    except RecursionError:
        raise InputError(str(path), "not valid JSON: nested too deeply") from None
