"""Parsers for what vision-language models actually write: points, choice letters, numbers with units,
and the `<think>...</think><answer>...</answer>` reasoning format.

Why one module: the rewards, `refspatial-gen eval` and the baselines must read a model's output the same
way, and every format here has a formatter beside it so tests can round-trip it (tests/test_rewards_parse.py).

Points come back as continuous pixel coordinates `(x, y)` of the image the question is about (origin top
left, y down; pixel `(i, j)` covers `[i, i+1) x [j, j+1)`), whatever the model's convention:

| convention | looks like | to pixels |
|---|---|---|
| `normalized` (RoboRefer, RefSpatial) | `[(0.510, 0.255)]` or a bare `(0.510, 0.255)` | `x * W` |
| `pixels` (Qwen2.5-VL) | `{"point_2d": [326, 122]}` or `(326, 122)` | the pixel's centre, `x + 0.5` |
| `qwen1000` (0-1000 relative) | `{"point_2d": [510, 255]}` or `(510, 255)` | `x / 1000 * W` |
| `molmo` (percent) | `<point x="51.0" y="25.5" alt="cup">cup</point>`, `<points x1=".." y1=".." ...>` | `x / 100 * W` |

`auto` (the default) reads Molmo tags as percent, `point_2d` JSON as absolute pixels, and tuples as
RoboRefer's evaluation script does: a tuple with a decimal point is normalised, an all-integer tuple is
absolute pixels. Pass the convention explicitly for 0-1000 outputs (they look like pixels).
"""

from __future__ import annotations

import json
import math
import re
from dataclasses import dataclass

POINT_CONVENTIONS = ("auto", "normalized", "pixels", "qwen1000", "molmo")
LETTERS = "ABCDEFGH"

_NUM = r"[-+]?(?:\d+\.?\d*|\.\d+)(?:[eE][-+]?\d+)?"
_TUPLE = re.compile(rf"\(\s*({_NUM})\s*,\s*({_NUM})\s*\)")
_MOLMO_ONE = re.compile(rf'<point\b[^>]*?\bx\s*=\s*"({_NUM})"[^>]*?\by\s*=\s*"({_NUM})"', re.I)
_MOLMO_MANY = re.compile(rf'\bx(\d+)\s*=\s*"({_NUM})"\s+y\1\s*=\s*"({_NUM})"', re.I)
_POINT2D = re.compile(rf'"point_2d"\s*:\s*\[\s*({_NUM})\s*,\s*({_NUM})\s*\]')
_BBOX2D = re.compile(rf'"bbox_2d"\s*:\s*\[\s*({_NUM})\s*,\s*({_NUM})\s*,\s*({_NUM})\s*,\s*({_NUM})\s*\]')
_ANSWER = re.compile(r"<answer>(.*?)</answer>", re.S)
_STRICT = re.compile(r"\s*<think>(.*?)</think>\s*<answer>(.*?)</answer>\s*", re.S)


# ----------------------------------------------------------------------------- output structure
def answer_part(text: str) -> str:
    """The text inside the last `<answer>...</answer>`, or the whole text when there is none."""
    found = _ANSWER.findall(text or "")
    return found[-1].strip() if found else (text or "").strip()


def split_reasoning(text: str) -> tuple[str, str] | None:
    """`(think, answer)` when the text is exactly `<think>...</think><answer>...</answer>` (whitespace
    around the tags allowed, one of each tag), else None."""
    t = text or ""
    if t.count("<think>") != 1 or t.count("</think>") != 1 or t.count("<answer>") != 1 or t.count("</answer>") != 1:
        return None
    m = _STRICT.fullmatch(t)
    return None if m is None else (m.group(1), m.group(2).strip())


# ----------------------------------------------------------------------------- points
def parse_points(text: str, width: int, height: int, convention: str = "auto") -> list[tuple[float, float]]:
    """Every point the answer part names, in continuous pixel coordinates (see the module docstring).
    An empty list means no point was found (a parse failure for a point question)."""
    if convention not in POINT_CONVENTIONS:
        raise ValueError(f"unknown point convention {convention!r} (choose from {', '.join(POINT_CONVENTIONS)})")
    t = answer_part(text)
    W, H = float(width), float(height)
    if convention in ("auto", "molmo"):
        pts = _molmo(t)
        if pts or convention == "molmo":
            return [(x / 100.0 * W, y / 100.0 * H) for x, y in pts]
    if convention in ("auto", "pixels", "qwen1000"):
        js = [(float(a), float(b)) for a, b in _POINT2D.findall(t)]
        js += [((float(a) + float(c)) / 2, (float(b) + float(d)) / 2) for a, b, c, d in _BBOX2D.findall(t)]
        if js:
            if convention == "qwen1000":
                return [(x / 1000.0 * W, y / 1000.0 * H) for x, y in js]
            return [(x + 0.5, y + 0.5) for x, y in js]
    out = []
    for a, b in _TUPLE.findall(t):
        x, y = float(a), float(b)
        if convention == "normalized" or (convention == "auto" and ("." in a or "." in b)):
            out.append((x * W, y * H))
        elif convention == "qwen1000":
            out.append((x / 1000.0 * W, y / 1000.0 * H))
        elif convention in ("pixels", "auto"):
            out.append((x + 0.5, y + 0.5))
    return out


def _molmo(t: str) -> list[tuple[float, float]]:
    pts = [(float(x), float(y)) for x, y in _MOLMO_ONE.findall(t)]
    for tag in re.findall(r"<points\b[^>]*>", t, re.I):
        pts += [(float(x), float(y)) for _, x, y in _MOLMO_MANY.findall(tag)]
    return pts


def format_points(points_px: list[tuple[float, float]], width: int, height: int, convention: str) -> str:
    """Write pixel points the way a model of `convention` would (used by tests and baselines)."""
    W, H = float(width), float(height)
    if convention == "normalized":
        return "[" + ", ".join(f"({x / W:.3f}, {y / H:.3f})" for x, y in points_px) + "]"
    if convention == "pixels":
        return json.dumps(
            [{"point_2d": [int(math.floor(x)), int(math.floor(y))], "label": "target"} for x, y in points_px]
        )
    if convention == "qwen1000":
        return json.dumps(
            [{"point_2d": [round(x / W * 1000), round(y / H * 1000)], "label": "target"} for x, y in points_px]
        )
    if convention == "molmo":
        if len(points_px) == 1:
            x, y = points_px[0]
            return f'<point x="{x / W * 100:.1f}" y="{y / H * 100:.1f}" alt="target">target</point>'
        attrs = " ".join(
            f'x{i + 1}="{x / W * 100:.1f}" y{i + 1}="{y / H * 100:.1f}"' for i, (x, y) in enumerate(points_px)
        )
        return f'<points {attrs} alt="target">target</points>'
    raise ValueError(f"no formatter for convention {convention!r}")


# ----------------------------------------------------------------------------- choices
def parse_choice(text: str, options: list[str]) -> int | None:
    """Index of the option the answer picks, or None (nothing, or more than one option named).

    Accepted: `(B)`, `(B) left`, `B`, `B)`, `B.`, `Answer: B`, `option B`, or the option's own text
    (`left`, `Yes, it is.`) when exactly one option appears as whole words.
    """
    t = answer_part(text)
    n = max(1, len(options))
    letters = LETTERS[:n]
    found = {m for m in re.findall(r"\(([A-H])\)", t) if m in letters}
    if len(found) == 1:
        return letters.index(found.pop())
    if len(found) > 1:
        return None
    m = re.match(r"^\s*([A-H])\s*(?:[).:,]|$)", t) or re.search(
        r"\b(?:answer|option|choice)\s*(?:is|:)?\s*([A-H])\b", t, re.I
    )
    if m and m.group(1) in letters:
        return letters.index(m.group(1))
    low = " " + re.sub(r"[^a-z0-9]+", " ", t.lower()) + " "
    hits = [
        i for i, o in enumerate(options) if o and (" " + re.sub(r"[^a-z0-9]+", " ", o.lower()).strip() + " ") in low
    ]
    if len(hits) == 1:
        return hits[0]
    if len(hits) > 1:  # a longer option can contain a shorter one ("left" in "to the left"): keep the longest
        longest = max(hits, key=lambda i: len(options[i]))
        if all(options[longest].lower().find(options[i].lower()) >= 0 for i in hits):
            return longest
    return None


# ----------------------------------------------------------------------------- numbers with units
LENGTH_UNITS = {  # unit word -> metres
    "m": 1.0,
    "meter": 1.0,
    "meters": 1.0,
    "metre": 1.0,
    "metres": 1.0,
    "cm": 0.01,
    "centimeter": 0.01,
    "centimeters": 0.01,
    "centimetre": 0.01,
    "centimetres": 0.01,
    "mm": 0.001,
    "millimeter": 0.001,
    "millimeters": 0.001,
    "millimetre": 0.001,
    "millimetres": 0.001,
    "ft": 0.3048,
    "foot": 0.3048,
    "feet": 0.3048,
    "'": 0.3048,
    "in": 0.0254,
    "inch": 0.0254,
    "inches": 0.0254,
    '"': 0.0254,
}
ANGLE_UNITS = {
    "deg": math.pi / 180,
    "degree": math.pi / 180,
    "degrees": math.pi / 180,
    "°": math.pi / 180,
    "rad": 1.0,
    "radian": 1.0,
    "radians": 1.0,
}
_UNIT_RE = "|".join(sorted((re.escape(u) for u in list(LENGTH_UNITS) + list(ANGLE_UNITS)), key=len, reverse=True))
_QTY = re.compile(rf"({_NUM})\s*({_UNIT_RE})?(?![A-Za-z])", re.I)


@dataclass(frozen=True)
class Quantity:
    value: float  # SI: metres or radians
    dimension: str  # "length" | "angle"


def parse_number(text: str, dimension: str, *, signed_by_direction: bool = False) -> float | None:
    """The quantity the answer states, in SI units (metres or radians), or None.

    `dimension` is "length" or "angle". Units: m/cm/mm/ft/in (and their words) for lengths, degrees / °
    / rad for angles; a bare number means metres or degrees. Adjacent length terms add up (`1 m 20 cm`,
    `5 ft 3 in`). With `signed_by_direction`, the words left/down make the value negative and right/up
    positive (the convention of `rotate left around 19.9 degrees`: + = right / up).
    """
    if dimension not in ("length", "angle"):
        raise ValueError(f"dimension must be 'length' or 'angle', got {dimension!r}")
    t = answer_part(text)
    terms: list[tuple[int, int, float]] = []  # (start, end, SI value) of compatible terms
    for m in _QTY.finditer(t):
        num, unit = m.group(1), (m.group(2) or "").lower()
        if unit == "in" and re.match(r"\s+(?:the|a|an|front|total)\b", t[m.end() :], re.I):
            unit = ""  # "3 in the box": a preposition, not inches
        scale = (LENGTH_UNITS if dimension == "length" else ANGLE_UNITS).get(unit)
        if unit and scale is None:
            continue  # a unit of the other dimension
        if not unit:
            scale = 1.0 if dimension == "length" else math.pi / 180
        terms.append((m.start(), m.end(), float(num) * scale))
    if not terms:
        return None
    value = terms[0][2]
    end = terms[0][1]
    for s, e, v in terms[1:]:  # "1 m 20 cm", "5 ft and 3 in": join terms separated only by space/and/comma
        if dimension == "length" and re.fullmatch(r"[\s,]*(?:and\s*)?", t[end:s]):
            value += v
            end = e
        else:
            break
    if signed_by_direction:
        words = set(re.findall(r"\b(left|right|up|down)\b", t.lower()))
        if words & {"left", "down"} and not words & {"right", "up"}:
            value = -abs(value)
        elif words & {"right", "up"} and not words & {"left", "down"}:
            value = abs(value)
    return value


def format_number(value_si: float, dimension: str, unit: str) -> str:
    """`0.35` metres -> `35 centimeters` etc. (tests and baselines)."""
    table = LENGTH_UNITS if dimension == "length" else ANGLE_UNITS
    return f"{value_si / table[unit]:.4g} {unit}"


# ----------------------------------------------------------------------------- reasoning steps
STEP_TYPES = ("Position", "Orientation", "Size")
_STEP = re.compile(r"^\s*\[(Position|Orientation|Size)\]\s*\[(.+?)\]\s*:\s*(.+?)\s*$")


@dataclass(frozen=True)
class Step:
    """One parsed `[Type] [phrase]: value` line; `value` is None when the value does not fit the type."""

    type: str
    phrase: str
    value: tuple[float, ...] | None


def normalise_phrase(p: str) -> str:
    """Phrase key for matching steps: lower case, single spaces, no surrounding quotes or full stop."""
    return re.sub(r"\s+", " ", p.strip().strip("\"'`.").lower())


def parse_step_value(kind: str, raw: str) -> tuple[float, ...] | None:
    """Position: `(x, y)` normalised; Orientation: `(a, b, c)`; Size: one length in metres (`0.20 m`,
    `20 cm`, `(0.200)`, `0.2`) or the older 3-vector `(w, d, h)` in metres."""
    nums = [float(x) for x in re.findall(_NUM, raw)]
    if kind == "Position":
        return tuple(nums) if len(nums) == 2 and raw.strip().startswith("(") else None
    if kind == "Orientation":
        return tuple(nums) if len(nums) == 3 else None
    if len(nums) == 3 and raw.strip().startswith("("):
        return tuple(nums)
    v = parse_number(raw, "length")
    return None if v is None or len(nums) != 1 else (v,)


def parse_steps(think: str) -> tuple[list[Step], int]:
    """The well-formed steps of a think block and the number of non-empty lines that are not."""
    steps: list[Step] = []
    bad = 0
    for line in (think or "").splitlines():
        if not line.strip():
            continue
        m = _STEP.match(line)
        if m is None:
            bad += 1
            continue
        value = parse_step_value(m.group(1), m.group(3))
        if value is None:
            bad += 1
        steps.append(Step(m.group(1), m.group(2), value))
    return steps, bad
