"""Template text variants: `{slot}` placeholders, `{a|b|c}` synonyms, `[optional part]`, nesting allowed.

Why a tiny grammar of our own: recipe authors write many phrasings in one line, and the compiler must
know every placeholder a variant uses (an unknown one is a load-time error, not a KeyError at run time).
A text compiles once to a tree; rendering walks it with the sample's generator (qa.sample_rng.SampleRng in
generation; anything with integers(n) and random()).
"""

from __future__ import annotations

import re
from collections.abc import Callable
from dataclasses import dataclass
from typing import Any

_IDENT = re.compile(r"^[A-Za-z_][A-Za-z0-9_]*(\.[A-Za-z_][A-Za-z0-9_]*)?$")


class TextSyntaxError(ValueError):
    """A malformed variant; the message says where (column) and what."""


@dataclass(frozen=True)
class Lit:
    text: str


@dataclass(frozen=True)
class Slot:
    name: str  # "target" or "rel.superlative"


@dataclass(frozen=True)
class Alt:
    options: tuple[Seq, ...]


@dataclass(frozen=True)
class Opt:
    body: Seq


@dataclass(frozen=True)
class Seq:
    parts: tuple[Lit | Slot | Alt | Opt, ...]


def parse(text: str) -> Seq:
    """Compile one variant. Raises TextSyntaxError on unbalanced brackets or empty placeholders."""
    seq, pos = _parse_seq(text, 0, closers="")
    if pos != len(text):
        raise TextSyntaxError(f"unexpected {text[pos]!r} at column {pos + 1}")
    return seq


def _parse_seq(text: str, pos: int, closers: str) -> tuple[Seq, int]:
    parts: list[Any] = []
    buf: list[str] = []
    while pos < len(text):
        ch = text[pos]
        if ch == "\\" and pos + 1 < len(text):
            buf.append(text[pos + 1])
            pos += 2
            continue
        if ch in closers or (ch == "|" and "}" in closers):
            break
        if ch == "|" and closers == "]":
            raise TextSyntaxError(
                f"'|' at column {pos + 1} inside [...] is plain text there; write [{{a|b}}] for alternatives "
                "(or \\| for a literal bar)"
            )
        if ch in "]}":
            raise TextSyntaxError(f"unbalanced {ch!r} at column {pos + 1}")
        if ch == "[":
            if buf:
                parts.append(Lit("".join(buf)))
                buf = []
            body, pos = _parse_seq(text, pos + 1, closers="]")
            if pos >= len(text) or text[pos] != "]":
                raise TextSyntaxError(f"unclosed '[' (opened before column {pos + 1})")
            parts.append(Opt(body))
            pos += 1
            continue
        if ch == "{":
            if buf:
                parts.append(Lit("".join(buf)))
                buf = []
            node, pos = _parse_brace(text, pos + 1)
            parts.append(node)
            continue
        buf.append(ch)
        pos += 1
    if buf:
        parts.append(Lit("".join(buf)))
    return Seq(tuple(parts)), pos


def _parse_brace(text: str, pos: int) -> tuple[Slot | Alt, int]:
    start = pos
    options: list[Seq] = []
    while True:
        seq, pos = _parse_seq(text, pos, closers="}")
        options.append(seq)
        if pos >= len(text):
            raise TextSyntaxError(f"unclosed '{{' (opened at column {start})")
        if text[pos] == "|":
            pos += 1
            continue
        pos += 1  # "}"
        break
    if len(options) == 1:
        raw = text[start : pos - 1].strip()
        if not _IDENT.match(raw):
            raise TextSyntaxError(f"placeholder {{{raw}}} at column {start} is not a name (use {{a|b}} for synonyms)")
        return Slot(raw), pos
    return Alt(tuple(options)), pos


_PLACEHOLDERS: dict[int, tuple[Seq, frozenset[Any]]] = {}


def placeholders(seq: Seq) -> frozenset[str]:
    """Every placeholder name a compiled variant can use (computed once per compiled variant)."""
    hit = _PLACEHOLDERS.get(id(seq))
    if hit is not None and hit[0] is seq:
        return hit[1]
    out = frozenset(_placeholders(seq))
    if len(_PLACEHOLDERS) > 100_000:
        _PLACEHOLDERS.clear()
    _PLACEHOLDERS[id(seq)] = (seq, out)
    return out


def required_placeholders(seq: Seq) -> frozenset[str]:
    """Placeholders every rendering of the variant writes: outside optional parts, and in every option of
    a synonym group."""
    out: set[str] = set()
    for p in seq.parts:
        if isinstance(p, Slot):
            out.add(p.name)
        elif isinstance(p, Alt):
            out |= frozenset.intersection(*(required_placeholders(o) for o in p.options))
    return frozenset(out)


def optional_only_placeholders(seq: Seq) -> frozenset[str]:
    """Placeholders the variant writes only inside optional `[...]` parts (some renderings omit them)."""
    inside: set[str] = set()

    def walk(s: Seq) -> None:
        for p in s.parts:
            if isinstance(p, Opt):
                inside.update(_placeholders(p.body))
            elif isinstance(p, Alt):
                for o in p.options:
                    walk(o)

    walk(seq)
    return frozenset(inside) - required_placeholders(seq)


def _placeholders(seq: Seq) -> set[str]:
    out: set[str] = set()
    for p in seq.parts:
        if isinstance(p, Slot):
            out.add(p.name)
        elif isinstance(p, Alt):
            for o in p.options:
                out |= _placeholders(o)
        elif isinstance(p, Opt):
            out |= _placeholders(p.body)
    return out


def render(seq: Seq, values: Callable[[str], str], rng: Any, p_optional: float = 0.5, sentence: bool = True) -> str:
    """Render with synonyms and optional parts drawn from `rng`; whitespace tidied, and the first letter
    capitalised when `sentence` (not for phrases inserted into a sentence)."""
    parts = seq.parts
    if not sentence and len(parts) == 1 and parts[0].__class__ is Lit:
        return _tidy_literal(parts[0].text)  # a fixed phrase ("to the left of"): no draws, tidied once
    out: list[str] = []
    _render(seq, values, rng, p_optional, out)
    return tidy("".join(out), sentence)


_TIDY_LITERALS: dict[str, str] = {}


def _tidy_literal(text: str) -> str:
    t = _TIDY_LITERALS.get(text)
    if t is None:
        if len(_TIDY_LITERALS) > 10_000:
            _TIDY_LITERALS.clear()
        t = _TIDY_LITERALS[text] = tidy(text, False)
    return t


# compiled parts: (0, text) literal, (1, name) slot, (2, options) synonyms, (3, body) optional part, with
# synonyms and optional parts that are plain words flattened to (4, texts) and (5, text): no recursion
_FLAT: dict[int, tuple[Seq, tuple[Any, ...]]] = {}


def _flat(seq: Seq) -> tuple[Any, ...]:
    hit = _FLAT.get(id(seq))
    if hit is not None and hit[0] is seq:
        return hit[1]
    ops: list[tuple[Any, ...]] = []
    for p in seq.parts:
        if p.__class__ is Lit:
            ops.append((0, p.text))
        elif p.__class__ is Slot:
            ops.append((1, p.name))
        elif p.__class__ is Alt:
            if all(len(o.parts) == 1 and o.parts[0].__class__ is Lit for o in p.options):
                ops.append((4, tuple(o.parts[0].text for o in p.options)))  # type: ignore[union-attr]
            else:
                ops.append((2, p.options))
        elif len(p.body.parts) == 1 and p.body.parts[0].__class__ is Lit:  # type: ignore[union-attr]
            ops.append((5, p.body.parts[0].text))  # type: ignore[union-attr]
        else:
            ops.append((3, p.body))  # type: ignore[union-attr]
    if len(_FLAT) > 100_000:
        _FLAT.clear()
    out = tuple(ops)
    _FLAT[id(seq)] = (seq, out)
    return out


def _render(seq: Seq, values: Callable[[str], str], rng: Any, p_opt: float, out: list[str]) -> None:
    """Append the rendered parts; draws from rng in part order (one integer per synonym group, one float per
    optional part), the same draws whatever the parts contain."""
    for kind, v in _flat(seq):
        if kind == 0:
            out.append(v)
        elif kind == 1:
            out.append(values(v))
        elif kind == 4:
            out.append(v[int(rng.integers(len(v)))])
        elif kind == 5:
            if rng.random() < p_opt:
                out.append(v)
        elif kind == 2:
            _render(v[int(rng.integers(len(v)))], values, rng, p_opt, out)
        elif rng.random() < p_opt:
            _render(v, values, rng, p_opt, out)


_SPACE_PUNCT = re.compile(r"\s+([,.?!;:])")
_SPACE_BEFORE_PUNCT = (" ,", " .", " ?", " !", " ;", " :")


def _group1(m: re.Match[str]) -> str:
    return m.group(1)


def tidy(s: str, sentence: bool = True) -> str:
    """Whitespace runs collapsed to one space, none before punctuation, none at the ends; the first letter
    capitalised when `sentence`. str.split() splits on exactly the characters regex whitespace matches (both
    use Unicode whitespace), so the join is a whitespace-run -> " " substitution plus strip, at string speed; the
    punctuation rule then only runs when a space precedes one."""
    s = " ".join(s.split())
    if " " in s and any(p in s for p in _SPACE_BEFORE_PUNCT):
        s = _SPACE_PUNCT.sub(_group1, s)
    return s[:1].upper() + s[1:] if s and sentence else s
