"""Per-family prompt templates (recipes/rewrite/*.yaml) and the chat messages built from one pair's facts.

Why data and not code: the wording of a prompt is tuned per model and per family; a recipe author edits
YAML. Every placeholder is checked at load, so a typo is a `file:line` error before any request is sent.
"""

from __future__ import annotations

import json
import string
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from refspatial_gen.core.errors import RecipeError, RecipeErrors
from refspatial_gen.rewrite.facts import Facts
from refspatial_gen.yamlpos import line_of, load_yaml

PLACEHOLDERS = ("question", "answer", "phrases", "words", "relations", "family", "hint")
_TOP = ("system", "user", "ask_answer", "examples", "families")
_EXAMPLE = ("question", "answer", "phrases", "words", "relations", "family", "rewrite")


@dataclass(frozen=True)
class Prompts:
    system: str
    user: str
    hints: dict[str, str]
    users: dict[str, str]  # per-family user message overrides
    examples: tuple[dict[str, Any], ...] = field(default_factory=tuple)
    path: str = ""
    ask_answer: bool = True  # the reply carries the answer too (checked to re-parse to the original)

    def messages(self, f: Facts) -> list[dict[str, str]]:
        """System prompt, few-shot turns, then this pair's facts."""
        msgs = [{"role": "system", "content": self.system}]
        for ex in self.examples:
            msgs.append(
                {
                    "role": "user",
                    "content": self._user(
                        ex["family"], ex["question"], ex["answer"], ex["phrases"], ex["words"], ex["relations"]
                    ),
                }
            )
            reply = {"question": ex["rewrite"], **({"answer": ex["answer"]} if self.ask_answer else {})}
            msgs.append({"role": "assistant", "content": json.dumps(reply)})
        msgs.append(
            {
                "role": "user",
                "content": self._user(f.family, f.body, f.answer, list(f.phrases), list(f.words), list(f.relations)),
            }
        )
        return msgs

    def _user(self, family: str, question: str, answer: str, phrases: list, words: list, relations: list) -> str:
        values = {
            "question": question,
            "answer": answer,
            "family": family,
            "phrases": "; ".join(f'"{p}"' for p in phrases) or "(none)",
            "words": ", ".join(words) or "(none)",
            "relations": ", ".join(relations) or "(none)",
        }
        hint = self.hints.get(family, self.hints.get("default", ""))
        values["hint"] = hint.format(**values, hint="")
        return self.users.get(family, self.user).format(**values)


def _check_text(text: Any, file: str, line: int | None, where: str, errors: list[RecipeError]) -> str:
    if not isinstance(text, str) or not text.strip():
        errors.append(RecipeError(file, line, f"{where} must be a non-empty string"))
        return ""
    try:
        names = [n for _, n, _, _ in string.Formatter().parse(text) if n is not None]
    except ValueError as e:
        errors.append(RecipeError(file, line, f"{where}: {e} (write literal braces as {{{{ and }}}})"))
        return ""
    for n in names:
        if n not in PLACEHOLDERS:
            errors.append(
                RecipeError(file, line, f"{where}: unknown placeholder {{{n}}} (known: {', '.join(PLACEHOLDERS)})")
            )
    return text


def load_prompts(path: str | Path) -> Prompts:
    """Load and check a prompt file. Raises RecipeErrors listing every problem."""
    file = str(path)
    data, lines = load_yaml(path)
    errors: list[RecipeError] = []
    if not isinstance(data, dict):
        raise RecipeError(file, 1, "a prompt file is a mapping with system, user, examples, families")
    for k in data:
        if k not in _TOP:
            errors.append(RecipeError(file, line_of(lines, (k,)), f"unknown key {k!r} (known: {', '.join(_TOP)})"))
    system = data.get("system")
    if not isinstance(system, str) or not system.strip():
        errors.append(RecipeError(file, line_of(lines, ("system",)), "system must be a non-empty string"))
        system = ""
    user = _check_text(data.get("user"), file, line_of(lines, ("user",)), "user", errors)
    hints: dict[str, str] = {}
    users: dict[str, str] = {}
    fams = data.get("families") or {}
    if not isinstance(fams, dict):
        errors.append(RecipeError(file, line_of(lines, ("families",)), "families must be a mapping"))
        fams = {}
    for fam, d in fams.items():
        ln = line_of(lines, ("families", fam))
        if not isinstance(d, dict) or set(d) - {"hint", "user"}:
            errors.append(RecipeError(file, ln, f"families.{fam} must be a mapping with hint and/or user"))
            continue
        if "hint" in d:
            hints[fam] = _check_text(d["hint"], file, ln, f"families.{fam}.hint", errors)
        if "user" in d:
            users[fam] = _check_text(d["user"], file, ln, f"families.{fam}.user", errors)
    examples = []
    for i, ex in enumerate(data.get("examples") or []):
        ln = line_of(lines, ("examples", i))
        if not isinstance(ex, dict) or set(ex) != set(_EXAMPLE):
            errors.append(RecipeError(file, ln, f"examples[{i}] needs exactly the keys {', '.join(_EXAMPLE)}"))
            continue
        examples.append(dict(ex))
    ask = data.get("ask_answer", True)
    if not isinstance(ask, bool):
        errors.append(RecipeError(file, line_of(lines, ("ask_answer",)), "ask_answer must be true or false"))
    if errors:
        raise RecipeErrors(errors)
    return Prompts(system.strip(), user, hints, users, tuple(examples), file, bool(ask))
