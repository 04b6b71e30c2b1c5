"""Shared pieces of the fuzz tests: JSON-like values, document mutations, fixed-seed settings.

Why a fixed seed (`derandomize=True`) and bounded example counts: the suite runs in CI; a failure must
reproduce on every machine, and the fast part must stay fast. Long runs are marked slow.
"""

from __future__ import annotations

import copy
from typing import Any

from hypothesis import HealthCheck, Phase, settings
from hypothesis import strategies as st

FAST = settings(max_examples=60, derandomize=True, deadline=None, database=None,
                suppress_health_check=[HealthCheck.function_scoped_fixture, HealthCheck.too_slow,
                                       HealthCheck.data_too_large])
# slow runs do not shrink a failure (shrinking can take many minutes): the first failing example is reported
SLOW = settings(FAST, max_examples=300, phases=[Phase.explicit, Phase.generate])

scalars = st.one_of(
    st.none(), st.booleans(), st.integers(min_value=-(2**70), max_value=2**70),
    st.floats(allow_nan=True, allow_infinity=True), st.text(max_size=12),
    st.sampled_from(["", "wide", "../../etc/passwd", "/etc/passwd", "NaN", "1e999", "-1", "0", "\0", "#", "!x"]))
json_values = st.recursive(scalars, lambda inner: st.one_of(st.lists(inner, max_size=4),
                                                            st.dictionaries(st.text(max_size=8), inner, max_size=4)),
                           max_leaves=12)


def paths(doc: Any, prefix: tuple = ()) -> list[tuple]:
    """Every key / index path inside a document (the root excluded)."""
    out = []
    items = doc.items() if isinstance(doc, dict) else enumerate(doc) if isinstance(doc, list) else []
    for k, v in items:
        out.append(prefix + (k,))
        out += paths(v, prefix + (k,))
    return out


def mutate(doc: Any, data: st.DataObject, rounds: int = 2) -> Any:
    """A copy of `doc` with a few random nodes replaced by random values or deleted."""
    doc = copy.deepcopy(doc)
    for _ in range(data.draw(st.integers(1, rounds), label="rounds")):
        ps = paths(doc)
        if not ps:
            return data.draw(json_values, label="root")
        p = data.draw(st.sampled_from(ps), label="path")
        parent = doc
        for k in p[:-1]:
            parent = parent[k]
        if data.draw(st.booleans(), label="delete") and isinstance(parent, dict):
            parent.pop(p[-1])
        else:
            parent[p[-1]] = data.draw(json_values, label="value")
    return doc
