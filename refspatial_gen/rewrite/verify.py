"""`verify`'s re-check of rewritten questions, from what a shard stores.

The rewrite stage judged each rewrite on the facts it sent to the model (the program's phrases). This
path starts again from the stored sample: the original question and suffix recorded in
`sample.meta["rewrite"]`, the scene graphs' phrases (every node phrase found in the original is a
referring phrase that must survive), the graphs' categories, colours and surfaces, and the answer's own
format (the choices re-written from `answer_struct`). The answer itself is re-checked against the scene by
`qa.verify` like any other pair, so a rewrite that changed what is asked fails there too.
"""

from __future__ import annotations

from typing import Any

from refspatial_gen.core.model import QAPair, Sample, SceneGraph
from refspatial_gen.rewrite import rules
from refspatial_gen.rewrite.check import Limits, body_reason, question_form

_LETTERS = "ABCDEFGH"


def _expected_suffix(qa: QAPair, original: str, stored: str) -> str | None:
    """Problem with the recorded suffix, or None: choices must be exactly the answer's options; a point
    instruction must end the original and read like one; a number question has none."""
    s = qa.answer_struct or {}
    kind = s.get("kind")
    if kind == "choice":
        want = " ".join(f"({_LETTERS[i]}) {o}".rstrip() for i, o in enumerate(s.get("options") or []))
        return None if stored == want else f"suffix {stored!r} is not the answer's options {want!r}"
    if kind in ("points", "region"):
        low = stored.lower()
        if not stored or "(x" not in low or not original.endswith(stored):
            return f"suffix {stored!r} is not the original's point-output instruction"
        return None
    return None if stored == "" else f"a {kind} question has no format suffix, got {stored!r}"


def _scene_words(graphs: list[SceneGraph]) -> tuple[list[str], frozenset[str], set[str]]:
    phrases, vocab, cats = [], set(rules.NOUNS) | set(rules.COLORS), set()
    for g in graphs:
        for n in g.nodes:
            phrases.extend(p.lower() for p in n.phrases)
            cats.add(n.category.lower())
            if isinstance(n.attributes.get("color"), str):
                vocab.add(n.attributes["color"].lower())
            for sup in (n.support, n.attributes.get("surface")):
                if isinstance(sup, str) and not sup.startswith("obj:"):
                    vocab.add(sup.lower().replace("_", " "))
    return phrases, frozenset(vocab | cats), cats


def _filter_words(program: list[dict]) -> tuple[str, ...]:
    return tuple(
        str(st["args"][k])
        for st in program
        if st.get("op") == "filter"
        for k in ("category", "color")
        if isinstance((st.get("args") or {}).get(k), str)
    )


def verify_rewrites(sample: Sample) -> list[dict[str, Any]]:
    """Failures of the sample's rewritten pairs: [{"sample_id", "qa_id", "template", "reason"}]."""
    meta = sample.meta.get("rewrite") or {}
    pairs = meta.get("pairs") or {}
    if not pairs:
        return []
    lim = meta.get("limits") or {}
    limits = Limits(
        int(lim.get("max_chars", Limits.max_chars)),
        int(lim.get("min_chars", Limits.min_chars)),
        float(lim.get("max_ratio", Limits.max_ratio)),
    )
    by_id = {q.qa_id: q for q in sample.qa}
    scene_phrases, vocab, _ = _scene_words(sample.graphs)
    out = []

    def fail(qa_id: str, template: str, reason: str) -> None:
        out.append({"sample_id": sample.sample_id, "qa_id": qa_id, "template": template, "reason": reason})

    for qa_id in sorted(pairs):
        rec = pairs[qa_id]
        qa = by_id.get(qa_id)
        if qa is None:
            fail(qa_id, "?", "rewrite record names a QA pair that is not in the sample")
            continue
        original, suffix = str(rec.get("original", "")), str(rec.get("suffix", ""))
        bad = _expected_suffix(qa, original, suffix)
        if bad is None and not (qa.question.endswith(suffix) and original.endswith(suffix)):
            bad = "the rewritten question does not end with the original's format suffix"
        if bad:
            fail(qa_id, qa.template, f"rewrite: {bad}")
            continue
        o_body = original[: len(original) - len(suffix)].rstrip()
        n_body = qa.question[: len(qa.question) - len(suffix)].rstrip()
        # every scene phrase the original names (longest first: "the cup" inside "the cup left of the box" is
        # kept through the longer one) must be in the rewrite as often
        _, counts = rules.mask_phrases(o_body, tuple(scene_phrases))
        keep = tuple(p for p, n in counts.items() if n)
        reason = body_reason(
            o_body, n_body, keep, _filter_words(qa.program), vocab, qa.answer, limits, question_form(qa.answer_struct)
        )
        if reason is not None and reason != "unchanged":
            fail(qa_id, qa.template, f"rewrite: {reason} (original {original!r})")
    return out


def with_rewrite_checks(verify_samples, samples) -> dict[str, Any]:
    """`verify_samples(samples)` with each sample's rewrite failures added (verify_dir's hook): a pair
    counts as failed once, whichever check found it; `rewritten` says how many pairs carry a rewrite."""
    extra: list[dict[str, Any]] = []
    n = 0

    def tap(it):
        nonlocal n
        for s in it:
            extra.extend(verify_rewrites(s))
            n += len(((s.meta.get("rewrite") or {}).get("pairs")) or {})
            yield s

    out = verify_samples(tap(samples))
    known = {(f["sample_id"], f["qa_id"]) for f in out["failures"]}
    new = {(f["sample_id"], f["qa_id"]) for f in extra} - known
    out["failed"] += len(new)
    out["passed"] -= len(new)
    out["failures"] = out["failures"] + extra
    out["rewritten"] = n
    return out
