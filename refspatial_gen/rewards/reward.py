"""Reward functions for reinforcement fine-tuning on refspatial-gen data, after RoboRefer's RFT appendix.

Every function is pure: (model output text, `Gold`) -> a number in [0, 1] (or None where it does not
apply). The RoboRefer paper's rewards:

- **outcome format** (`format_reward`): 1 when the output is exactly `<think>...</think><answer>...</answer>`
  and the answer parses for the question's kind. For a QA without a gold trace (single-step questions
  carry none) a bare answer is accepted too.
- **point** (`point_reward`, the paper's): the share of predicted points whose L1 distance to the gold
  point is at most 50 px. Used for the answer of point and placement questions.
- **region** (`region_reward`, this project's variant): 1 for a point inside the target's visible mask or
  the free-space region, else `max(0, 1 - d / 50 px)` with d the distance to the nearest mask pixel;
  averaged over predicted points. Why: about half of a 50 px disc around a gold point lies off a small
  object, so the paper's reward pays for points that miss it.
- **process format** (`process_format_reward`, weight 0.25): 1 when the think block has at least one step
  and every non-empty line is `[Position|Orientation|Size] [target phrase]: value` with a value of the
  right shape; None for QAs without gold reasoning.
- **process accuracy** (`process_accuracy_reward`, weight 0.25): the share of gold key steps that the
  output states correctly, matched by (type, target phrase), order-invariant: Position within 50 px (L1),
  Orientation cosine > 0.8, Size within +-15 % of the gold length in metres. None without gold key steps
  or gold reasoning.

Size convention: a Size key step is one length in metres (`value: [0.2]`, RoboRefer's scalar). Older data
stored the box size `[w, d, h]`: a scalar prediction is then compared with the largest of the three, a
3-vector prediction component by component (each within 15 %).

Choice and number answers have an accuracy reward in place of the point reward: 1 for the right letter;
1 for a number within 25 % (lengths) or 15 degrees (angles) of the gold value.

`score()` returns every component, their weighted sum (`reward`, weights 1 / 1 / 0.25 / 0.25 over the
components that apply), that sum divided by the largest it can be (`reward_norm`, 1.0 = perfect) and
`success`: the benchmark's criterion (share of predicted points inside the mask; right letter; number
within tolerance).
"""

from __future__ import annotations

import math

import numpy as np

from refspatial_gen.rewards.gold import Gold, coerce_gold
from refspatial_gen.rewards.parse import (
    answer_part,
    normalise_phrase,
    parse_choice,
    parse_number,
    parse_points,
    parse_steps,
    split_reasoning,
)

POINT_L1_PX = 50.0
REGION_FALLOFF_PX = 50.0
ORIENTATION_COS = 0.8
SIZE_REL_TOL = 0.15
LENGTH_REL_TOL = 0.25
ANGLE_TOL_RAD = math.radians(15.0)
WEIGHTS = {"format": 1.0, "accuracy": 1.0, "process_format": 0.25, "process_accuracy": 0.25}
VARIANTS = ("paper", "region")


# ----------------------------------------------------------------------------- answer parsing per kind
def parse_answer(text: str, gold: Gold, point_convention: str = "auto"):
    """The answer as the gold's kind reads it: pixel points, an option index, or an SI number; None/[] on failure."""
    W, H = gold.image_size
    if gold.kind in ("points", "region"):
        return parse_points(text, W, H, point_convention)
    if gold.kind == "choice":
        return parse_choice(text, gold.options)
    if gold.kind == "number":
        dim = "angle" if gold.unit == "rad" else "length"
        return parse_number(text, dim, signed_by_direction=str(gold.quantity or "").startswith("rotation"))
    raise ValueError(f"unknown answer kind {gold.kind!r}")


def parsed_ok(answer, gold: Gold) -> bool:
    return bool(answer) if gold.kind in ("points", "region") else answer is not None


# ----------------------------------------------------------------------------- outcome rewards
def format_reward(text: str, gold: Gold | dict | str, point_convention: str = "auto") -> float:
    """Outcome format: the `<think>...</think><answer>...</answer>` structure with a parseable answer."""
    g = coerce_gold(gold)
    parts = split_reasoning(text)
    if parts is None:
        if g.reasoning or "<think>" in (text or "") or "<answer>" in (text or ""):
            return 0.0
        body = text
    else:
        body = parts[1]
    return 1.0 if parsed_ok(parse_answer(body, g, point_convention), g) else 0.0


def point_reward(points_px: list[tuple[float, float]], gold: Gold | dict | str) -> float:
    """The paper's point reward: share of predicted points within 50 px (L1) of the gold point."""
    g = coerce_gold(gold)
    if not points_px or not g.points:
        return 0.0
    W, H = g.image_size
    gx, gy = g.points[0][0] * W, g.points[0][1] * H
    return float(np.mean([abs(x - gx) + abs(y - gy) <= POINT_L1_PX for x, y in points_px]))


def inside_mask(points_px: list[tuple[float, float]], gold: Gold) -> np.ndarray:
    """Per point: does it fall in a mask pixel (pixel = floor of the coordinate; off-image = no)."""
    m = gold.mask_array()
    if m is None:
        raise ValueError(f"{gold.qa_id}: gold has no mask")
    H, W = m.shape
    out = []
    for x, y in points_px:
        i, j = math.floor(x), math.floor(y)
        out.append(0 <= i < W and 0 <= j < H and bool(m[j, i]))
    return np.asarray(out, bool)


def region_reward(points_px: list[tuple[float, float]], gold: Gold | dict | str) -> float:
    """Region variant: 1 inside the mask, else `max(0, 1 - d/50 px)` to the nearest mask pixel; mean over points."""
    g = coerce_gold(gold)
    if not points_px:
        return 0.0
    inside = inside_mask(points_px, g)
    centres = g.mask_centres()
    vals = []
    for (x, y), ins in zip(points_px, inside):
        if ins:
            vals.append(1.0)
        elif not len(centres):
            vals.append(0.0)
        else:
            d = float(np.sqrt(((centres - (x, y)) ** 2).sum(axis=1).min()))
            vals.append(max(0.0, 1.0 - d / REGION_FALLOFF_PX))
    return float(np.mean(vals))


def number_ok(value: float | None, gold: Gold) -> bool:
    if value is None or gold.value is None or not math.isfinite(value):
        return False
    if gold.unit == "rad":
        return abs(value - gold.value) <= ANGLE_TOL_RAD
    return abs(value - gold.value) <= LENGTH_REL_TOL * abs(gold.value)


def accuracy_reward(
    text: str, gold: Gold | dict | str, variant: str = "paper", point_convention: str = "auto"
) -> float:
    """The answer's reward: point (paper) or region reward for points/placement, right letter, number in tolerance."""
    if variant not in VARIANTS:
        raise ValueError(f"variant must be one of {VARIANTS}, got {variant!r}")
    g = coerce_gold(gold)
    ans = parse_answer(text, g, point_convention)
    if g.kind in ("points", "region"):
        return point_reward(ans, g) if variant == "paper" else region_reward(ans, g)
    if g.kind == "choice":
        return 1.0 if ans is not None and g.letter is not None and ans == "ABCDEFGH".find(g.letter) else 0.0
    return 1.0 if number_ok(ans, g) else 0.0


def success(text: str, gold: Gold | dict | str, point_convention: str = "auto") -> float:
    """The benchmark's criterion: share of predicted points inside the mask (RefSpatial-Bench), or 0/1."""
    g = coerce_gold(gold)
    ans = parse_answer(text, g, point_convention)
    if g.kind in ("points", "region"):
        return float(inside_mask(ans, g).mean()) if ans else 0.0
    return accuracy_reward(text, g, "paper", point_convention)


# ----------------------------------------------------------------------------- process rewards
def process_format_reward(text: str, gold: Gold | dict | str) -> float | None:
    """1 when every think line is a well-formed step (and there is one); None without gold reasoning."""
    g = coerce_gold(gold)
    if not g.reasoning:
        return None
    parts = split_reasoning(text)
    if parts is None:
        return 0.0
    steps, bad = parse_steps(parts[0])
    return 1.0 if steps and not bad else 0.0


def step_correct(kind: str, pred: tuple[float, ...], gold_value: list[float], image_size: tuple[int, int]) -> bool:
    """One step's check: Position L1 <= 50 px; Orientation cosine > 0.8; Size within 15 %."""
    W, H = image_size
    gv = [float(v) for v in (gold_value if isinstance(gold_value, (list, tuple)) else [gold_value])]
    if kind == "Position":
        return len(pred) == 2 and len(gv) == 2 and abs(pred[0] - gv[0]) * W + abs(pred[1] - gv[1]) * H <= POINT_L1_PX
    if kind == "Orientation":
        a, b = np.asarray(pred, float), np.asarray(gv, float)
        if a.shape != (3,) or b.shape != (3,) or not np.linalg.norm(a) or not np.linalg.norm(b):
            return False
        return float(a @ b / (np.linalg.norm(a) * np.linalg.norm(b))) > ORIENTATION_COS
    if kind == "Size":
        if len(gv) == 3 and len(pred) == 3:
            return all(abs(p - q) <= SIZE_REL_TOL * abs(q) for p, q in zip(pred, gv))
        ref = max(gv) if len(gv) == 3 else gv[0]
        return len(pred) == 1 and abs(pred[0] - ref) <= SIZE_REL_TOL * abs(ref)
    return False


def process_accuracy_reward(text: str, gold: Gold | dict | str) -> float | None:
    """Share of gold key steps stated correctly, matched by (type, phrase) in any order; None if none apply."""
    g = coerce_gold(gold)
    if not g.reasoning or not g.key_steps:
        return None
    parts = split_reasoning(text)
    if parts is None:
        return 0.0
    steps, _ = parse_steps(parts[0])
    by_key: dict[tuple[str, str], list[tuple[float, ...]]] = {}
    for s in steps:
        if s.value is not None:
            by_key.setdefault((s.type, normalise_phrase(s.phrase)), []).append(s.value)
    hits = 0
    for k in g.key_steps:
        preds = by_key.get((k["type"], normalise_phrase(k["phrase"])), [])
        hits += any(step_correct(k["type"], p, k["value"], g.image_size) for p in preds)
    return hits / len(g.key_steps)


# ----------------------------------------------------------------------------- everything at once
def score(text: str, gold: Gold | dict | str, variant: str = "region", point_convention: str = "auto") -> dict:
    """All components for one output: format, accuracy, process_format, process_accuracy (None = n/a),
    reward (weighted sum), reward_norm (divided by its maximum), success, parsed (answer parsed)."""
    g = coerce_gold(gold)
    comp = {
        "format": format_reward(text, g, point_convention),
        "accuracy": accuracy_reward(answer_part(text), g, variant, point_convention),
        "process_format": process_format_reward(text, g),
        "process_accuracy": process_accuracy_reward(text, g),
    }
    total = sum(WEIGHTS[k] * v for k, v in comp.items() if v is not None)
    top = sum(WEIGHTS[k] for k, v in comp.items() if v is not None)
    ans = parse_answer(answer_part(text), g, point_convention)
    return {
        **comp,
        "reward": total,
        "reward_norm": total / top,
        "success": success(answer_part(text), g, point_convention),
        "parsed": parsed_ok(ans, g),
    }
