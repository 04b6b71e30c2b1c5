"""What a rewrite may change and what it must keep, gathered from one QA pair and its scene.

A question is split into its body (rewritten) and its output-format suffix (the choices "(A) yes (B) no"
or the point-output instruction), which is re-attached verbatim. The body's facts are the object phrases
the program names (kept verbatim), the category and colour words its filters use, the relations, and
the scene's vocabulary of other nouns (a rewrite may name none of them that the original did not).
"""

from __future__ import annotations

import re
from dataclasses import dataclass
from typing import Any

from refspatial_gen.core.model import QAPair, SceneGraph
from refspatial_gen.rewrite import rules

_LETTERS = "ABCDEFGH"
# a sentence that starts the point-output instruction (any template's own instruction included)
_INSTRUCTION_SENTENCE = re.compile(r"tuple|coordinat|normali[sz]ed|\[\(", re.IGNORECASE)


@dataclass(frozen=True)
class Facts:
    """One QA pair as the rewrite stage sees it."""

    qa_id: str
    family: str
    kind: str  # answer kind: points, region, choice, number
    form: str  # the question it must stay: point, yesno, choice, number (check.question_form)
    body: str
    suffix: str  # "" when the question has none (numbers)
    answer: str
    phrases: tuple[str, ...]  # object phrases named in the body, in program order
    words: tuple[str, ...]  # category / colour words the program's filters use
    relations: tuple[str, ...]
    vocab: frozenset[str]  # nouns and colours a rewrite must not add (scene + generic lists)


def choices_text(options: list[str]) -> str:
    return " ".join(f"({_LETTERS[i]}) {o}".rstrip() for i, o in enumerate(options))


def _point_instructions() -> list[str]:
    from refspatial_gen.qa.lexicon import POINT_INSTRUCTIONS

    return [s.replace("\\[", "[").replace("\\]", "]") for s in POINT_INSTRUCTIONS]


def split_suffix(question: str, answer_struct: dict[str, Any]) -> tuple[str, str] | None:
    """(body, suffix), or None when the format text cannot be found where the answer kind needs it."""
    kind = (answer_struct or {}).get("kind")
    if kind == "choice":
        suffix = choices_text(list(answer_struct.get("options") or []))
        if not question.endswith(suffix):
            return None
        return question[: len(question) - len(suffix)].rstrip(), suffix
    if kind in ("points", "region"):
        for ins in _point_instructions():
            if question.endswith(" " + ins):
                return question[: -len(ins) - 1], ins
        for m in re.finditer(r"(?<=[.?!])\s+", question):
            rest = question[m.end() :]
            first = re.split(r"(?<=[.?!])\s+", rest, maxsplit=1)[0]
            if _INSTRUCTION_SENTENCE.search(first):
                return question[: m.start()], rest
        return None
    return question, ""


def _walk(x: Any):
    if isinstance(x, dict):
        yield x
        for v in x.values():
            yield from _walk(v)
    elif isinstance(x, list):
        for v in x:
            yield from _walk(v)


def program_phrases(program: list[dict]) -> tuple[list[str], list[str]]:
    """Object phrases (in program order, unique) and filter words (category, colour) of a program."""
    phrases: list[str] = []
    fwords: list[str] = []
    for st in program:
        args = st.get("args") or {}
        for d in _walk(args):
            p = d.get("phrase")
            if isinstance(p, str) and "object" in d and p not in phrases:
                phrases.append(p)
        if st.get("op") == "filter":
            for k in ("category", "color"):
                v = args.get(k)
                if isinstance(v, str) and v not in fwords:
                    fwords.append(v)
    return phrases, fwords


def _written(word: str, question: str) -> str:
    """The name the question uses for a filter word: the word itself or one of its curated synonyms."""
    from refspatial_gen.qa.lexicon import category_synonyms

    low = question.lower()
    if re.search(rf"\b{re.escape(word.lower())}", low):
        return word
    return next((s for s in category_synonyms(word) if re.search(rf"\b{re.escape(s)}", low)), word)


def scene_vocab(graphs: list[SceneGraph]) -> frozenset[str]:
    """Every noun and colour a rewrite could use to name an object: the scene's and generic ones."""
    v = set(rules.NOUNS) | set(rules.COLORS)
    for g in graphs:
        for n in g.nodes:
            v.add(n.category.lower())
            c = n.attributes.get("color")
            if isinstance(c, str):
                v.add(c.lower())
            if isinstance(n.support, str) and not n.support.startswith("obj:"):
                v.add(n.support.lower().replace("_", " "))
            sf = n.attributes.get("surface")
            if isinstance(sf, str):
                v.add(sf.lower().replace("_", " "))
    return frozenset(x for x in v if x)


def qa_facts(qa: QAPair, graphs: list[SceneGraph]) -> Facts | None:
    """The pair's facts, or None when its format suffix cannot be found (it is then not rewritten)."""
    split = split_suffix(qa.question, qa.answer_struct)
    if split is None:
        return None
    body, suffix = split
    prog, fwords = program_phrases(qa.program)
    fwords = [_written(w, qa.question) for w in fwords]  # a category the question names by a synonym
    # the program's phrases, and any other unique phrase of the scene the body contains (longest first)
    scene = [p for g in graphs for n in g.nodes for p in n.phrases]
    _, counts = rules.mask_phrases(body, tuple(p.lower() for p in prog + scene))
    phrases = [p for p in dict.fromkeys(prog + scene) if counts[p.lower()] > 0]
    from refspatial_gen.rewrite.check import question_form

    return Facts(
        qa_id=qa.qa_id,
        family=qa.family,
        kind=str((qa.answer_struct or {}).get("kind")),
        form=question_form(qa.answer_struct),
        body=body,
        suffix=suffix,
        answer=qa.answer,
        phrases=tuple(phrases),
        words=tuple(fwords),
        relations=tuple(qa.relations),
        vocab=scene_vocab(graphs),
    )
