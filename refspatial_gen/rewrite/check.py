"""Is a rewritten question body the same question? Each rule returns a stable reason code or None.

The rules (RefSpatial's, made checkable): every object phrase verbatim and as often as in the original
(exactly once in practice); no other object named; the filter's category and colour words kept; the same
spatial concepts, negation and perspective; the same numbers (no leaked value, no lost ordinal); no answer
word; the output format left to the suffix; a bounded length. `answer_matches` checks the answer the model
returned re-parses to the original structured answer. Used by the rewrite stage before a rewrite is kept
(`rewrite.stage`) and by `verify` on stored rewrites (`rewrite.verify`, which gathers the facts itself).
"""

from __future__ import annotations

import re
from dataclasses import dataclass

from refspatial_gen.rewrite import rules

REASONS = (
    "server_error",
    "bad_json",
    "answer_changed",
    "empty",
    "too_long",
    "too_short",
    "not_one_line",
    "format_text",
    "phrase_missing",
    "phrase_repeated",
    "order_changed",
    "extra_object",
    "word_missing",
    "relation_changed",
    "perspective_changed",
    "number_changed",
    "leaked_answer",
    "question_form",
    "unchanged",
    "no_suffix",
)

_ENUM = re.compile(r"(?<![\d.])\d\.(?=\s)")  # "1. left of the cup 2. ..." enumeration markers
_FORMAT = re.compile(r"\(\s*[A-H]\s*\)|\[\s*\(|tuple|normali[sz]ed coordinates", re.IGNORECASE)
_POINTS = re.compile(r"\(\s*(-?\d+(?:\.\d+)?)\s*,\s*(-?\d+(?:\.\d+)?)\s*\)")


@dataclass(frozen=True)
class Limits:
    max_chars: int = 320  # body length at most
    min_chars: int = 8
    max_ratio: float = 2.5  # body at most this many times the original body (plus 40 characters)


def question_form(answer_struct: dict) -> str:
    """point, yesno, choice or number: what kind of question the answer needs."""
    kind = (answer_struct or {}).get("kind")
    if kind == "choice":
        return "yesno" if sorted(answer_struct.get("options") or []) == ["no", "yes"] else "choice"
    return "number" if kind == "number" else "point"


def body_reason(
    original: str,
    new: str,
    phrases: tuple[str, ...],
    fwords: tuple[str, ...],
    vocab: frozenset[str],
    answer: str,
    limits: Limits,
    form: str | None = None,
) -> str | None:
    """Why `new` is not an acceptable rewrite of the question body `original` (None: acceptable). `form`
    (question_form): the rewrite must still ask that kind of question."""
    if not new.strip():
        return "empty"
    if "\n" in new.strip() or "\r" in new:
        return "not_one_line"
    if len(new) > min(limits.max_chars, int(limits.max_ratio * len(original)) + 40):
        return "too_long"
    if len(new) < limits.min_chars:
        return "too_short"
    if _FORMAT.search(new) and not _FORMAT.search(original):
        return "format_text"
    lp = tuple(p.lower() for p in phrases)
    o_masked, o_counts = rules.mask_phrases(original, lp)
    n_masked, n_counts = rules.mask_phrases(new, lp)
    for p in lp:
        if n_counts[p] == 0:
            return "phrase_missing"
        if n_counts[p] != o_counts[p]:
            return "phrase_repeated"
    if rules.phrase_order(new, lp) != rules.phrase_order(original, lp):
        return "order_changed"  # the same phrases in another order may swap roles (A closer to B than C)
    if rules.nouns_in(n_masked, vocab) - rules.nouns_in(o_masked, vocab) - set(w.lower() for w in fwords):
        return "extra_object"
    if rules.nouns_in(o_masked, frozenset(w.lower() for w in fwords)) - rules.nouns_in(
        n_masked, frozenset(w.lower() for w in fwords)
    ):
        return "word_missing"
    nw = set(rules.words(n_masked)) - set(rules.words(o_masked))
    if nw.intersection(rules.ANSWER_WORDS) or _answer_named(n_masked, o_masked, answer):
        return "leaked_answer"
    if rules.numbers(_ENUM.sub(" ", n_masked)) != rules.numbers(_ENUM.sub(" ", o_masked)):
        return "number_changed"
    if rules.concepts(n_masked) != rules.concepts(o_masked):
        return "relation_changed"
    lo, ln = o_masked.lower(), n_masked.lower()
    if any((p in lo) != (p in ln) for p in rules.PERSPECTIVES) or any(
        p in ln and p not in lo for p in rules.OBJECT_FRAME
    ):
        return "perspective_changed"
    if form is not None and rules.asks_for(original, form) and not rules.asks_for(new, form):
        return "question_form"
    if _norm(new) == _norm(original):
        return "unchanged"
    return None


def _answer_named(new: str, original: str, answer: str) -> bool:
    """The answer text itself (beyond a bare letter) appears in the new body but not in the original."""
    a = re.sub(r"^\([A-H]\)\s*", "", answer.strip()).strip().lower()
    if len(a) < 3:
        return False
    return a in new.lower() and a not in original.lower()


def _norm(s: str) -> str:
    return re.sub(r"\s+", " ", s.strip().lower())


def answer_matches(original: str, returned: str | None) -> bool:
    """The returned answer is the original, or parses to the same structured answer (points, letter, number)."""
    if returned is None:
        return False
    a, b = _norm(original), _norm(str(returned))
    if a == b:
        return True
    pa, pb = _POINTS.findall(a), _POINTS.findall(b)
    if pa:
        return len(pa) == len(pb) and all(
            abs(float(x1) - float(x2)) < 1e-9 and abs(float(y1) - float(y2)) < 1e-9
            for (x1, y1), (x2, y2) in zip(pa, pb)
        )
    la, lb = re.match(r"^\(?([a-h])\)", a), re.match(r"^\(?([a-h])\)?(?:\s|$|\.)", b)
    if la:
        return bool(lb) and la.group(1) == lb.group(1)
    na, nb = re.findall(r"-?\d+(?:\.\d+)?", a), re.findall(r"-?\d+(?:\.\d+)?", b)
    if na:
        unit = lambda s: re.sub(r"[^a-z ]", "", s).split()  # noqa: E731 - words of the answer (unit, direction)
        return nb[:1] == na[:1] and unit(a) == unit(b)
    return False


def assemble(body: str, suffix: str, original_body: str) -> str:
    """The new question: body tidied (capital first letter, the original's closing mark), then the suffix."""
    body = " ".join(body.strip().strip('"').split())
    if body and body[0].islower():
        body = body[0].upper() + body[1:]
    end = original_body.rstrip()[-1:] if original_body.rstrip() else ""
    if body and body[-1] not in ".?!:" and end in ".?!:":
        body += end
    return f"{body} {suffix}" if suffix else body
