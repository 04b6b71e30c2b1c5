"""verify's own check of the nesting rule (qa/nesting.py): an object named inside the described object's
relative clauses is named directly, not through a third object. Reads only the stored program record and
matches the phrase forms itself (no import of the generator's rule)."""

from __future__ import annotations

import re
from collections.abc import Iterator
from typing import Any

from refspatial_gen.core.model import QAPair


def walk(x: Any) -> Iterator[dict[str, Any]]:
    """Every dict inside a program record argument."""
    if isinstance(x, dict):
        yield x
        for v in x.values():
            yield from walk(v)
    elif isinstance(x, list):
        for v in x:
            yield from walk(v)


_ANCHORED = re.compile(r"\b(closest to|farthest from|on) the\b")


def check_nesting(qa: QAPair) -> list[str]:
    """An object named inside the described object's relative clauses (an anchor of a step that narrows a set:
    its record reads `in`, or of `choose`) must be named directly, not through a third object (qa/nesting.py's rule)."""
    out = []
    for k, st in enumerate(qa.program):
        args = st.get("args") or {}
        if "in" not in args and st.get("op") != "choose":
            continue
        for name in ("anchor", "anchors"):
            for v in walk(args.get(name)):
                if isinstance(v, dict) and isinstance(v.get("phrase"), str) and _ANCHORED.search(v["phrase"].lower()):
                    out.append(f"step {k + 1} ({st['op']}): nested phrase {v['phrase']!r} inside a relative clause")
    return out
