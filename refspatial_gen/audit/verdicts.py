"""Verdicts on audit items (right / wrong / ambiguous + a note) in a JSONL file, and their summary.

Why JSONL, appended: a verdict is never lost to a crash of the page or the server, and a reviewer can
change their mind (the last verdict for an item wins). The summary gives rates per stratum with Wilson
95% intervals, because a rate from 30 judged pairs without its interval invites over-reading.
"""

from __future__ import annotations

import json
import math
from dataclasses import dataclass
from pathlib import Path
from typing import Any

VERDICTS = ("right", "wrong", "ambiguous")
VERDICT_FILE = "verdicts.jsonl"
SAMPLE_FILE = "sample.jsonl"


@dataclass(frozen=True)
class Verdict:
    item_id: str
    verdict: str
    note: str = ""

    def to_json(self) -> dict[str, Any]:
        return {"item_id": self.item_id, "verdict": self.verdict, "note": self.note}


def check_verdict(item_id: str, verdict: str, known: set[str]) -> None:
    """Raise ValueError for an unknown item or verdict word (the page and the CLI share this rule)."""
    if verdict not in VERDICTS:
        raise ValueError(f"verdict must be one of {', '.join(VERDICTS)}, not {verdict!r}")
    if item_id not in known:
        raise ValueError(f"no item {item_id!r} in this audit")


def read_items(audit_dir: Path) -> list[dict[str, Any]]:
    path = Path(audit_dir) / SAMPLE_FILE
    if not path.is_file():
        raise FileNotFoundError(f"{path}: not an audit folder (make one with `refspatial-gen audit DIR... --out D`)")
    return [json.loads(line) for line in path.read_text(encoding="utf-8").splitlines() if line.strip()]


def append_verdict(audit_dir: Path, v: Verdict) -> None:
    """Append one verdict (validated against the audit's items)."""
    known = {it["item_id"] for it in read_items(audit_dir)}
    check_verdict(v.item_id, v.verdict, known)
    with open(Path(audit_dir) / VERDICT_FILE, "a", encoding="utf-8") as fh:
        fh.write(json.dumps(v.to_json(), sort_keys=True, ensure_ascii=False) + "\n")


def read_verdicts(audit_dir: Path) -> dict[str, Verdict]:
    """item id -> its latest verdict. Malformed lines raise ValueError naming the line."""
    path = Path(audit_dir) / VERDICT_FILE
    out: dict[str, Verdict] = {}
    if not path.is_file():
        return out
    for k, line in enumerate(path.read_text(encoding="utf-8").splitlines(), 1):
        if not line.strip():
            continue
        try:
            d = json.loads(line)
            v = Verdict(str(d["item_id"]), str(d["verdict"]), str(d.get("note", "")))
        except (ValueError, KeyError, TypeError) as e:
            raise ValueError(f"{path}:{k}: not a verdict line ({e})") from None
        if v.verdict not in VERDICTS:
            raise ValueError(f"{path}:{k}: unknown verdict {v.verdict!r}")
        out[v.item_id] = v
    return out


def wilson(k: int, n: int, z: float = 1.959964) -> tuple[float, float]:
    """Wilson score interval for k successes in n trials (95% by default); (0, 1) when n = 0."""
    if n == 0:
        return (0.0, 1.0)
    p = k / n
    den = 1 + z * z / n
    mid = (p + z * z / (2 * n)) / den
    half = z * math.sqrt(p * (1 - p) / n + z * z / (4 * n * n)) / den
    return (max(0.0, mid - half), min(1.0, mid + half))


def _rates(rows: list[tuple[dict[str, Any], Verdict]]) -> dict[str, Any]:
    n = len(rows)
    out: dict[str, Any] = {"judged": n}
    for word in VERDICTS:
        k = sum(1 for _, v in rows if v.verdict == word)
        lo, hi = wilson(k, n)
        out[word] = {"count": k, "rate": round(k / n, 4) if n else None, "ci95": [round(lo, 4), round(hi, 4)]}
    return out


def summarise(audit_dir: Path) -> dict[str, Any]:
    """Rates overall, per dataset label, per family, per step count and per (label, family, steps)
    stratum, the items still unjudged, and every wrong or ambiguous item with its note."""
    items = read_items(audit_dir)
    verdicts = read_verdicts(audit_dir)
    judged = [(it, verdicts[it["item_id"]]) for it in items if it["item_id"] in verdicts]
    out: dict[str, Any] = {"items": len(items), "unjudged": len(items) - len(judged), "overall": _rates(judged)}
    for name, key in (
        ("by_label", lambda it: it["label"]),
        ("by_family", lambda it: it["family"]),
        ("by_steps", lambda it: str(it["steps"])),
    ):
        groups: dict[str, list] = {}
        for it, v in judged:
            groups.setdefault(key(it), []).append((it, v))
        out[name] = {g: _rates(rows) for g, rows in sorted(groups.items())}
    strata: dict[str, list] = {}
    for it, v in judged:
        strata.setdefault(f"{it['label']}/{it['family']}/{it['steps']}", []).append((it, v))
    out["by_stratum"] = {s: _rates(rows) for s, rows in sorted(strata.items())}
    out["problems"] = [
        {**{k: it[k] for k in ("item_id", "family", "steps", "label")}, "verdict": v.verdict, "note": v.note}
        for it, v in judged
        if v.verdict != "right"
    ]
    return out


def summary_markdown(s: dict[str, Any]) -> str:
    """The summary as Markdown tables (for docs/quality.md)."""

    def pct(r: dict[str, Any], word: str) -> str:
        x = r[word]
        if x["rate"] is None:
            return "-"
        return f"{x['count']} ({100 * x['rate']:.1f}%, {100 * x['ci95'][0]:.1f}–{100 * x['ci95'][1]:.1f})"

    lines = [
        f"{s['items']} items, {s['items'] - s['unjudged']} judged.",
        "",
        "| group | judged | right | wrong (95% CI) | ambiguous (95% CI) |",
        "|---|---|---|---|---|",
    ]
    rows = [("**all**", s["overall"])] + [
        (f"{k}", r) for sec in ("by_label", "by_family", "by_steps") for k, r in s[sec].items()
    ]
    for name, r in rows:
        lines.append(f"| {name} | {r['judged']} | {r['right']['count']} | {pct(r, 'wrong')} | {pct(r, 'ambiguous')} |")
    if s["problems"]:
        lines += ["", "| item | verdict | note |", "|---|---|---|"]
        lines += [
            f"| `{p['item_id']}` ({p['family']}, {p['steps']} steps) | {p['verdict']} | {p['note']} |"
            for p in s["problems"]
        ]
    return "\n".join(lines) + "\n"
