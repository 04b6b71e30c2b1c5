"""How varied is a dataset's language? The distinct-question share with the scene taken out.

A question is reduced to its wording: every referring phrase of the sample's scene graphs is masked
(longest first, any case), every number is masked, and the output-format suffix (choices, point
instruction) is dropped. The share is distinct reduced questions / questions. `categories=True` also masks
bare category words ("the cup that is ..."), a stricter reading. Reads only metadata (no pixels).
"""

from __future__ import annotations

import re
from collections import Counter, defaultdict
from pathlib import Path
from typing import Any

from refspatial_gen.qa.lexicon import category_synonyms
from refspatial_gen.rewrite import rules
from refspatial_gen.rewrite.facts import split_suffix

_NUM = re.compile(r"\d+(?:\.\d+)?")


def reduce_question(question: str, answer_struct: dict, phrases: tuple[str, ...], cats: tuple[str, ...] = ()) -> str:
    split = split_suffix(question, answer_struct)
    body = split[0] if split is not None else question
    body, _ = rules.mask_phrases(body, phrases)
    body = body.replace("\u2063", "<obj>")
    for c in sorted(set(cats), key=lambda s: (-len(s), s)):
        body = re.sub(r"(?<![A-Za-z0-9])" + re.escape(c) + r"(?:s|es)?(?![A-Za-z0-9])", "<cat>", body, flags=re.I)
    body = _NUM.sub("<n>", body)
    return " ".join(body.split())


def language_stats(d: str | Path, categories: bool = False, top: int = 10) -> dict[str, Any]:
    """{"questions", "distinct", "share", "rewritten", "by_family": {fam: {questions, distinct, share}},
    "most_repeated": [[count, wording], ...]} over every shard in DIR/index.json."""
    from refspatial_gen.shards.index import read_index
    from refspatial_gen.shards.reader import read_sample_meta

    d = Path(d)
    seen: Counter = Counter()
    fam: dict[str, Counter] = defaultdict(Counter)
    rewritten = 0
    for row in read_index(d)["shards"]:
        for m in read_sample_meta(d / row["name"]):
            phrases = tuple({p.lower() for g in m["graphs"] for n in g["nodes"] for p in n["phrases"]})
            cats = tuple({n["category"] for g in m["graphs"] for n in g["nodes"]}) if categories else ()
            cats += tuple(s for c in cats for s in category_synonyms(c))  # the names templates may use instead
            rewritten += len(((m.get("meta") or {}).get("rewrite") or {}).get("pairs") or {})
            for q in m["qa"]:
                r = reduce_question(q["question"], q["answer_struct"], phrases, cats)
                seen[r] += 1
                fam[q["family"]][r] += 1
    n = sum(seen.values())

    def share(c: Counter) -> dict[str, Any]:
        t = sum(c.values())
        return {"questions": t, "distinct": len(c), "share": round(len(c) / t, 4) if t else 0.0}

    return {
        **share(seen),
        "rewritten": rewritten,
        "masked": "phrases+categories" if categories else "phrases",
        "by_family": {k: share(v) for k, v in sorted(fam.items())},
        "most_repeated": [[c, w] for w, c in sorted(seen.items(), key=lambda kv: (-kv[1], kv[0]))[:top]] if n else [],
    }
