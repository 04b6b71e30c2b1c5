"""Baselines (predictions without a model) and the shortcut audit.

- `gold`: each QA pair's own gold text (trace or answer): must score success 1.0 (a check of the scorer).
- `centre`: the image centre `[(0.500, 0.500)]` for point and free-space questions; no answer otherwise.
- `frequent-choice`: the letter that is most often right among choice questions with the same number of
  options; for numbers the median gold value of the same quantity; no answer for points.
- `text-only`: the question's words alone. Choice: the option named first in the question stem (before
  the options), else (A). Points: a point from the stem's direction words (left/right/top/bottom/near/far
  shift it from the centre). Numbers: the median gold value of the quantity the question names.
- `random`: a uniform option, a uniform point, a length drawn uniformly in log scale between 0.05 and 5 m,
  an angle uniform in [0, 180] degrees, a camera rotation uniform in [-90, 90] degrees, from
  `numpy.random.default_rng(seed)`.

The audit runs text-only and frequent-choice and compares each template's success with chance: the
expected success of the random baseline, worked out exactly per QA pair (1/options; mask area / image
area; the share of the random number's range within the answer tolerance). A template whose text-only
success has a 95 % interval lying wholly above chance + `LEAK_MARGIN` is reported as leaking its answer:
its wording, or the narrow spread of its answers, gives the answer away without the image.
"""

from __future__ import annotations

import re
from collections import Counter
from statistics import median

import numpy as np

from refspatial_gen.eval.dataset import Item
from refspatial_gen.eval.score import wilson
from refspatial_gen.rewards.parse import LETTERS
from refspatial_gen.rewards.reward import ANGLE_TOL_RAD, LENGTH_REL_TOL

BASELINES = ("gold", "centre", "frequent-choice", "text-only", "random")
LEAK_MARGIN = 0.15
_CENTRE = "[(0.500, 0.500)]"
LENGTH_RANGE = (0.05, 5.0)  # metres, log-uniform
ANGLE_RANGE = (0.0, np.pi)
ROTATION_RANGE = (-np.pi / 2, np.pi / 2)


def _number_range(it: Item) -> tuple[float, float]:
    if it.gold.unit != "rad":
        return LENGTH_RANGE
    return ROTATION_RANGE if str(it.gold.quantity).startswith("rotation") else ANGLE_RANGE


def chance(it: Item) -> float | None:
    """Expected success of the random baseline on one QA pair (exact, not sampled)."""
    g = it.gold
    if g.kind == "choice":
        return 1.0 / max(1, len(g.options))
    if g.kind in ("points", "region"):
        m = g.mask_array()
        return None if m is None else float(m.mean())
    if g.kind == "number" and g.value is not None:
        lo, hi = _number_range(it)
        if g.unit != "rad":
            if g.value <= 0:
                return 0.0
            a, b = max(lo, (1 - LENGTH_REL_TOL) * g.value), min(hi, (1 + LENGTH_REL_TOL) * g.value)
            return max(0.0, np.log(b / a)) / np.log(hi / lo) if b > a else 0.0
        a, b = max(lo, g.value - ANGLE_TOL_RAD), min(hi, g.value + ANGLE_TOL_RAD)
        return max(0.0, b - a) / (hi - lo)
    return None


def mean_chance(items: list[Item]) -> float | None:
    vals = [c for c in (chance(it) for it in items) if c is not None]
    return sum(vals) / len(vals) if vals else None


def _fmt_number(value: float, unit: str | None, quantity: str = "") -> str:
    if unit == "rad" and quantity.startswith("rotation"):
        word = (
            ("right" if value > 0 else "left") if quantity.endswith("horizontal") else ("up" if value > 0 else "down")
        )
        return f"rotate {word} around {abs(np.degrees(value)):.1f} degrees"
    if unit == "rad":
        return f"{np.degrees(value):.1f} degrees"
    return f"{value:.2f} meters"


def _medians(items: list[Item]) -> dict[str, float]:
    by_q: dict[str, list[float]] = {}
    for it in items:
        if it.gold.kind == "number":
            by_q.setdefault(str(it.gold.quantity), []).append(float(it.gold.value))
    return {q: median(v) for q, v in by_q.items()}


def _stem(question: str) -> str:
    """The question without its inline options `(A) ... (B) ...`."""
    m = re.search(r"\(A\)", question)
    return question[: m.start()] if m else question


def text_only_choice(question: str, options: list[str]) -> int:
    """Index of the option whose text appears first in the stem (whole words), else 0."""
    stem = " " + re.sub(r"[^a-z0-9]+", " ", _stem(question).lower()) + " "
    best, pos = 0, None
    for i, o in enumerate(options):
        key = " " + re.sub(r"[^a-z0-9]+", " ", o.lower()).strip() + " "
        j = stem.find(key) if key.strip() else -1
        if j >= 0 and (pos is None or j < pos):
            best, pos = i, j
    return best


def text_only_point(question: str) -> tuple[float, float]:
    """A point from direction words: left/right move x to 0.3/0.7, top/above/far to y 0.35, bottom/below/near 0.65."""
    w = set(re.findall(r"[a-z]+", _stem(question).lower()))
    x = (
        0.3
        if w & {"left", "leftmost"} and not w & {"right", "rightmost"}
        else 0.7
        if w & {"right", "rightmost"} and not w & {"left", "leftmost"}
        else 0.5
    )
    up = w & {"top", "above", "far", "farthest", "behind", "topmost", "back"}
    down = w & {"bottom", "below", "near", "nearest", "front", "bottommost", "closest"}
    y = 0.35 if up and not down else 0.65 if down and not up else 0.5
    return x, y


def predict(name: str, items: list[Item], seed: int = 0) -> dict[str, str]:
    """Predictions (id -> text) of one baseline; QA pairs it does not answer get "" (a parse failure)."""
    if name not in BASELINES:
        raise ValueError(f"unknown baseline {name!r} (choose from {', '.join(BASELINES)})")
    rng = np.random.default_rng(seed)
    medians = _medians(items)
    freq: dict[int, str] = {}
    if name == "frequent-choice":
        by_n: dict[int, Counter] = {}
        for it in items:
            if it.gold.kind == "choice" and it.gold.letter:
                by_n.setdefault(len(it.gold.options), Counter())[it.gold.letter] += 1
        freq = {n: sorted(c.items(), key=lambda kv: (-kv[1], kv[0]))[0][0] for n, c in by_n.items()}
    out: dict[str, str] = {it.id: "" for it in items}
    for it in items:
        g = it.gold
        if name == "gold":
            out[it.id] = it.gold_text
        elif g.kind in ("points", "region"):
            if name == "centre":
                out[it.id] = _CENTRE
            elif name == "text-only":
                x, y = text_only_point(it.question)
                out[it.id] = f"[({x:.3f}, {y:.3f})]"
            elif name == "random":
                x, y = rng.random(2)
                out[it.id] = f"[({x:.3f}, {y:.3f})]"
        elif g.kind == "choice":
            n = max(1, len(g.options))
            if name == "frequent-choice":
                out[it.id] = f"({freq.get(len(g.options), 'A')})"
            elif name == "text-only":
                out[it.id] = f"({LETTERS[text_only_choice(it.question, g.options)]})"
            elif name == "random":
                out[it.id] = f"({LETTERS[int(rng.integers(n))]})"
        elif g.kind == "number":
            if name in ("frequent-choice", "text-only"):
                out[it.id] = _fmt_number(medians[str(g.quantity)], g.unit, str(g.quantity))
            elif name == "random":
                lo, hi = _number_range(it)
                v = (
                    float(np.exp(rng.uniform(np.log(lo), np.log(hi))))
                    if g.unit != "rad"
                    else float(rng.uniform(lo, hi))
                )
                out[it.id] = _fmt_number(v, g.unit, str(g.quantity))
    return out


def audit(items: list[Item], records_by_baseline: dict[str, list[dict]]) -> list[dict]:
    """Per template: chance, text-only and frequent-choice success with intervals, and whether it leaks."""
    rows = []
    templates = sorted({it.template for it in items})
    for t in templates:
        its = [it for it in items if it.template == t]
        ids = {it.id for it in its}
        chance = mean_chance(its)
        row = {"template": t, "family": its[0].family, "n": len(its), "chance": chance}
        for b, recs in records_by_baseline.items():
            sel = [r for r in recs if r["id"] in ids]
            k = sum(r["success"] for r in sel)
            row[b] = {"success_rate": k / len(sel) if sel else 0.0, "ci95": list(wilson(k, len(sel)))}
        to = row.get("text-only")
        row["leaks"] = bool(chance is not None and to is not None and to["ci95"][0] > chance + LEAK_MARGIN)
        rows.append(row)
    return rows
