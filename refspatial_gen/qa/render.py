"""Text of answers and reasoning traces, per shared/spec/formats.md.

Why separate: the exact strings are a contract with trainers (RefSpatial conventions) and with the
verifier, which parses them back; keeping every format in one place keeps them consistent.
"""

from __future__ import annotations

import math
from typing import Any

from refspatial_gen.core.model import KeyStep

LETTERS = "ABCDEFGH"


def fmt_point(p: tuple[float, float]) -> str:
    return f"({p[0]:.3f}, {p[1]:.3f})"


def fmt_points(points: list[tuple[float, float]]) -> str:
    """`[(0.510, 0.255)]`: normalised, three decimals."""
    return "[" + ", ".join(fmt_point(p) for p in points) + "]"


def fmt_choices(options: list[str]) -> str:
    """`(A) yes (B) no`."""
    return " ".join(f"({LETTERS[i]}) {o}".rstrip() for i, o in enumerate(options))


# unit -> (singular, plural, metres per unit). Lengths are written as people write them (RefSpatial varies
# m / cm / feet / inches by magnitude): the unit is drawn from the QA's own generator, by magnitude.
LENGTH_WORDS = {
    "m": ("meter", "meters", 1.0),
    "cm": ("centimeter", "centimeters", 0.01),
    "ft": ("foot", "feet", 0.3048),
    "in": ("inch", "inches", 0.0254),
}
# (below this many metres, ((unit, cumulative probability), ...)): under 1 m mostly cm or inches
UNIT_MIX = (
    (1.0, (("cm", 0.55), ("in", 0.9), ("m", 1.0))),
    (3.0, (("m", 0.55), ("ft", 0.9), ("cm", 1.0))),
    (float("inf"), (("m", 0.7), ("ft", 1.0))),
)


def length_decimals(unit: str, value: float) -> int:
    """Decimals a length is written with in `unit` (value in that unit): whole centimetres and inches from
    10 up, one decimal below; metres two decimals below 10 m, one above; feet one decimal."""
    if unit in ("cm", "in"):
        return 0 if value >= 9.95 else 1
    if unit == "m":
        return 2 if value < 9.995 else 1
    return 1


def length_unit(metres: float, rng: Any) -> str:
    """The unit for a length, drawn by magnitude (one `random()` draw)."""
    u = rng.random()
    for limit, mix in UNIT_MIX:
        if metres < limit:
            for unit, cum in mix:
                if u < cum:
                    return unit
    return "m"


def fmt_length(metres: float, rng: Any = None, unit: str | None = None) -> str:
    """A length with a unit by magnitude (`35 centimeters`, `13.8 inches`, `1.42 meters`, `4.7 feet`), the
    unit drawn from `rng`; without one (and no `unit`), centimetres under a metre, else metres."""
    if unit is None:
        unit = length_unit(metres, rng) if rng is not None else ("cm" if metres < 1.0 else "m")
    one, many, scale = LENGTH_WORDS[unit]
    v = metres / scale
    text = f"{v:.{length_decimals(unit, v)}f}"
    return f"{text} {one if text == '1' else many}"


def fmt_angle(rad: float) -> str:
    return f"{math.degrees(rad):.1f} degrees"


def fmt_turn(rad: float, axis: str) -> str:
    """`rotate left around 19.9 degrees` (+ = object to the right / above: rotate right / up)."""
    if axis == "horizontal":
        word = "right" if rad > 0 else "left"
    else:
        word = "up" if rad > 0 else "down"
    return f"rotate {word} around {abs(math.degrees(rad)):.1f} degrees"


def fmt_key_value(ks: KeyStep) -> str:
    if ks.type == "Position":
        return fmt_point((ks.value[0], ks.value[1]))
    if ks.type == "Size" and len(ks.value) == 1:
        return f"{ks.value[0]:.3f} m"  # RoboRefer's Size step: one length in metres
    return "(" + ", ".join(f"{v:.3f}" for v in ks.value) + ")"


def trace_lines(key_steps: list[KeyStep]) -> list[str]:
    return [f"[{k.type}] [{k.phrase}]: {fmt_key_value(k)}" for k in key_steps]


def fmt_trace(key_steps: list[KeyStep], answer: str) -> str:
    """`<think>[Position] [the red cup]: (0.510, 0.255)\n...</think><answer>...</answer>`."""
    return "<think>" + "\n".join(trace_lines(key_steps)) + "</think><answer>" + answer + "</answer>"


def round_key(values: Any) -> list[float]:
    return [round(float(v), 3) for v in values]
