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


def fmt_length(metres: float) -> str:
    """Lengths under a metre in centimetres (`35 centimeters`), longer ones in metres (`1.42 meters`)."""
    if metres < 1.0:
        cm = round(metres * 100.0)
        return f"{cm} centimeter" + ("s" if cm != 1 else "")
    return f"{metres:.2f} meters"


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
    if ks.type == "Orientation":
        return "(" + ", ".join(f"{v:.3f}" for v in ks.value) + ")"
    return "(" + ", ".join(f"{v:.3f}" for v in ks.value) + ")"


def trace_lines(key_steps: list[KeyStep]) -> list[str]:
    return [f"[{k.type}] [{k.phrase}]: {fmt_key_value(k)}" for k in key_steps]


def fmt_trace(key_steps: list[KeyStep], answer: str) -> str:
    """`<think>[Position] [the red cup]: (0.510, 0.255)\n...</think><answer>...</answer>`."""
    return "<think>" + "\n".join(trace_lines(key_steps)) + "</think><answer>" + answer + "</answer>"


def round_key(values: Any) -> list[float]:
    return [round(float(v), 3) for v in values]
