"""Reading a predictions file: JSON lines `{"id": <QA id>, "text": <raw model output>}`.

Nothing is skipped silently: malformed lines (not JSON, not an object, `id` or `text` missing or not a
string), ids the dataset does not have, and ids given twice are each listed with their line numbers;
QA pairs without a prediction are counted as missing (and scored as failures by `score.evaluate`).
For a duplicate id the first line is used.
"""

from __future__ import annotations

import json
from collections.abc import Iterable
from dataclasses import dataclass, field
from pathlib import Path


@dataclass
class Predictions:
    texts: dict[str, str] = field(default_factory=dict)  # id -> text (first occurrence)
    malformed: list[tuple[int, str]] = field(default_factory=list)  # (line number, why)
    unknown: list[tuple[int, str]] = field(default_factory=list)  # (line number, id)
    duplicates: list[tuple[int, str]] = field(default_factory=list)  # (line number, id) of repeats
    missing: list[str] = field(default_factory=list)  # dataset ids without a prediction
    lines: int = 0

    def problems(self) -> dict[str, int]:
        return {
            "malformed_lines": len(self.malformed),
            "unknown_ids": len(self.unknown),
            "duplicate_ids": len(self.duplicates),
            "missing_ids": len(self.missing),
        }

    def problem_lines(self, limit: int = 20) -> list[str]:
        """Readable lines for the terminal and the report (first `limit` of each kind)."""
        out = [f"line {n}: malformed: {why}" for n, why in self.malformed[:limit]]
        out += [
            f"line {n}: unknown id {i!r} (not in the dataset or not in the evaluated splits)"
            for n, i in self.unknown[:limit]
        ]
        out += [f"line {n}: duplicate id {i!r} (the first prediction is used)" for n, i in self.duplicates[:limit]]
        out += [f"missing prediction for {i!r} (scored as a failure)" for i in self.missing[:limit]]
        return out


def parse_predictions(lines: Iterable[str], known_ids: Iterable[str]) -> Predictions:
    """Validate prediction lines against the dataset's ids."""
    known = list(known_ids)
    known_set = set(known)
    p = Predictions()
    for n, line in enumerate(lines, 1):
        p.lines = n
        if not line.strip():
            continue
        try:
            d = json.loads(line)
        except json.JSONDecodeError as e:
            p.malformed.append((n, f"not JSON ({e.msg} at column {e.colno})"))
            continue
        if not isinstance(d, dict):
            p.malformed.append((n, f"a JSON {type(d).__name__}, not an object"))
            continue
        if not isinstance(d.get("id"), str):
            p.malformed.append((n, "no string 'id'"))
            continue
        if not isinstance(d.get("text"), str):
            p.malformed.append((n, f"no string 'text' for id {d['id']!r}"))
            continue
        i = d["id"]
        if i not in known_set:
            p.unknown.append((n, i))
        elif i in p.texts:
            p.duplicates.append((n, i))
        else:
            p.texts[i] = d["text"]
    p.missing = [i for i in known if i not in p.texts]
    return p


def read_predictions(path: Path | str, known_ids: Iterable[str]) -> Predictions:
    """`parse_predictions` over a file (UTF-8); raises OSError / UnicodeDecodeError naming the file."""
    path = Path(path)
    try:
        text = path.read_text(encoding="utf-8")
    except UnicodeDecodeError as e:
        raise ValueError(f"{path}: not UTF-8 text ({e.reason} at byte {e.start})") from e
    return parse_predictions(text.splitlines(), known_ids)
