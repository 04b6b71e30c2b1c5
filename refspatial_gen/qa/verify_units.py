"""Lengths read back for `verify`: written answers (`35 centimeters`, `13.8 inches`, `1.42 meters`, `4.7 feet`)
and Size key steps.

Why its own module: the verifier must not share the generator's formatting code (qa/render.py). This reads
a length as a person would, checks that it is written with the precision its unit takes (whole centimetres
and inches from 10 up, one decimal below; metres two decimals below 10, one above; feet one decimal), and
returns the value in metres with the rounding that precision allows.
"""

from __future__ import annotations

import re
from typing import Any

LENGTHS = ("distance", "depth", "height", "width")  # quantities answered as lengths
_LENGTH = re.compile(r"^(\d+(?:\.(\d+))?) (meters?|centimeters?|feet|foot|inch|inches)$")
_METRES = {"meter": 1.0, "centimeter": 0.01, "foot": 0.3048, "feet": 0.3048, "inch": 0.0254, "inches": 0.0254}


def stated_length(text: str) -> tuple[float, float] | str:
    """(metres, tolerance in metres) of a written length, or what is wrong with it."""
    m = _LENGTH.match(text.strip())
    if m is None:
        return f"{text!r} is not a number with a length unit (meters, centimeters, feet, inches)"
    num, frac, unit = m.group(1), m.group(2) or "", m.group(3)
    value = float(num)
    per = _METRES.get(unit, _METRES.get(unit.rstrip("s"), 0.0))
    decimals = len(frac)
    if unit in ("feet", "foot"):
        want = 1
    elif unit.startswith(("centimeter", "inch")):
        want = 0 if value >= 10 else 1
    else:
        want = 2 if value < 10 else 1
    if decimals != want:
        return f"{text!r}: {unit} are written with {want} decimal(s) at this size"
    singular = unit in ("meter", "centimeter", "foot", "inch")
    if singular != (num == "1"):
        return f"{text!r}: unit {unit!r} does not agree with the number"
    return value * per, 0.5 * 10.0**-decimals * per + 1e-9


def check_length_text(answer: str, metres: float) -> list[str]:
    """Problems of a written length answer against the value it must state (in metres)."""
    stated = stated_length(answer)
    if isinstance(stated, str):
        return [f"answer text: {stated}"]
    if abs(stated[0] - metres) > stated[1]:
        return [f"answer text {answer!r} does not render the value {metres:.4f} m"]
    return []


KEY_TOL = 1.5e-3  # key-step values are rounded to 3 decimals


def check_size_step(ks: Any, ref: tuple[float, float, float], volume: float) -> list[str]:
    """A Size step states one length in metres (RoboRefer's scalar): the box's height, larger horizontal
    extent or the side of a cube of its volume, as its `measure` says; its `extent` is the box's full size."""
    want = {"height": ref[2], "width": ref[0], "volume": volume ** (1.0 / 3.0)}.get(ks.measure)
    out = []
    if want is None or len(ks.value) != 1:
        return [f"key step Size {ks.phrase!r}: value {ks.value} / measure {ks.measure!r} is not one named length"]
    if abs(ks.value[0] - want) > KEY_TOL:
        out.append(f"key step Size {ks.phrase!r} {ks.measure} {ks.value[0]} differs from the box's {want:.3f}")
    if ks.extent is None or any(abs(a - b) > KEY_TOL for a, b in zip(ks.extent, ref)):
        out.append(f"key step Size {ks.phrase!r} extent {ks.extent} differs from the box {[round(r, 3) for r in ref]}")
    return out
