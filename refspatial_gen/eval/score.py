"""Scoring predictions against the evaluation set and summarising them with 95 % intervals.

Per QA pair: `rewards.score` (format, accuracy, process rewards, success). A missing prediction scores 0
everywhere and is counted as `missing`; a prediction whose answer does not parse for its question's
kind is a `parse_failure` (and scores what the rewards give it, usually 0).

Success is the benchmark's criterion: for point and free-space answers the share of predicted points
inside the target's mask (RefSpatial-Bench), else 0 or 1; rates are means of it, with Wilson score
intervals (z = 1.96) on (sum, n). Rows group by family, template, relation (a QA pair counts once under
each relation it asks), step count, source and split.
"""

from __future__ import annotations

import math
from typing import Any

from refspatial_gen.eval.dataset import Item
from refspatial_gen.eval.predictions import Predictions
from refspatial_gen.rewards.reward import WEIGHTS, score

Z95 = 1.959964
GROUPS = ("family", "template", "relation", "steps", "source", "split")


def wilson(k: float, n: int, z: float = Z95) -> tuple[float, float]:
    """Wilson score interval for k successes in n trials (k may be fractional: multi-point answers)."""
    if n <= 0:
        return (0.0, 1.0)
    p = min(max(k / n, 0.0), 1.0)
    den = 1.0 + z * z / n
    centre = (p + z * z / (2 * n)) / den
    half = z * math.sqrt(p * (1 - p) / n + z * z / (4 * n * n)) / den
    return (max(0.0, centre - half), min(1.0, centre + half))


def evaluate(
    items: list[Item], preds: Predictions, variant: str = "region", point_convention: str = "auto"
) -> list[dict]:
    """One record per item: id, missing, parsed, success, reward components (None = not applicable)."""
    out = []
    for it in items:
        text = preds.texts.get(it.id)
        if text is None:
            rec = {
                "id": it.id,
                "missing": True,
                "parsed": False,
                "success": 0.0,
                "reward": 0.0,
                "reward_norm": 0.0,
                **{k: (0.0 if k in ("format", "accuracy") or _applies(k, it) else None) for k in WEIGHTS},
            }
        else:
            rec = {
                "id": it.id,
                "missing": False,
                **score(text, it.gold, variant=variant, point_convention=point_convention),
            }
        out.append(rec)
    return out


def _applies(component: str, it: Item) -> bool:
    if component == "process_format":
        return it.gold.reasoning
    if component == "process_accuracy":
        return it.gold.reasoning and bool(it.gold.key_steps)
    return True


def _keys(it: Item, group: str) -> list[str]:
    if group == "relation":
        return sorted(set(it.relations)) or ["(none)"]
    if group == "steps":
        return [str(it.steps)]
    return [str(getattr(it, group))]


def _row(recs: list[dict]) -> dict[str, Any]:
    n = len(recs)
    k = sum(r["success"] for r in recs)
    lo, hi = wilson(k, n)
    return {
        "n": n,
        "success_rate": k / n if n else 0.0,
        "ci95": [lo, hi],
        "reward": sum(r["reward_norm"] for r in recs) / n if n else 0.0,
        "parse_failures": sum(1 for r in recs if not r["missing"] and not r["parsed"]),
    }


def summarise(items: list[Item], records: list[dict], preds: Predictions) -> dict[str, Any]:
    """The whole report as one dict (what `eval --json` prints)."""
    by_id = {r["id"]: r for r in records}
    total = _row(records)
    comps = {}
    for c in WEIGHTS:
        vals = [r[c] for r in records if r[c] is not None]
        comps[c] = {"mean": sum(vals) / len(vals) if vals else None, "n": len(vals), "weight": WEIGHTS[c]}
    out: dict[str, Any] = {
        **total,
        "components": comps,
        "missing": sum(r["missing"] for r in records),
        "problems": preds.problems(),
    }
    for g in GROUPS:
        groups: dict[str, list[dict]] = {}
        for it in items:
            for key in _keys(it, g):
                groups.setdefault(key, []).append(by_id[it.id])
        order = sorted(groups, key=lambda s: (int(s) if g == "steps" else 0, s))
        out[f"by_{g}"] = {key: _row(groups[key]) for key in order}
    return out
