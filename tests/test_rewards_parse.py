"""Parsers of model outputs: every format round-trips (hypothesis), and the ambiguous cases are decided as documented."""

import math

import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from refspatial_gen.rewards.parse import (LENGTH_UNITS, answer_part, format_number, format_points, parse_choice,
                                          parse_number, parse_points, parse_step_value, parse_steps, split_reasoning)

sizes = st.tuples(st.integers(16, 2000), st.integers(16, 2000))


@st.composite
def image_points(draw):
    W, H = draw(sizes)
    n = draw(st.integers(1, 4))
    pts = [(draw(st.floats(0, W, exclude_max=True)), draw(st.floats(0, H, exclude_max=True))) for _ in range(n)]
    return W, H, pts


# quantisation of each convention in pixels: 3 decimals, whole pixels, 0-1000, 0.1 percent
_TOL = {"normalized": lambda W, H: (0.0005 * W + 1e-6, 0.0005 * H + 1e-6), "pixels": lambda W, H: (0.5 + 1e-9, 0.5 + 1e-9),
        "qwen1000": lambda W, H: (0.0005 * W + 1e-6, 0.0005 * H + 1e-6), "molmo": lambda W, H: (0.0005 * W + 1e-6, 0.0005 * H + 1e-6)}


@settings(max_examples=200, deadline=None)
@given(image_points(), st.sampled_from(sorted(_TOL)), st.booleans())
def test_points_round_trip_every_convention(data, conv, auto):
    W, H, pts = data
    text = format_points(pts, W, H, conv)
    # qwen 0-1000 looks like pixels: it needs its convention named; the others are read by "auto" too
    got = parse_points(text, W, H, "auto" if auto and conv != "qwen1000" else conv)
    assert len(got) == len(pts)
    tx, ty = _TOL[conv](W, H)
    for (x, y), (gx, gy) in zip(pts, got):
        if conv == "pixels":  # absolute pixels name the pixel: its centre comes back
            assert (math.floor(gx), math.floor(gy)) == (math.floor(x), math.floor(y))
        else:
            assert abs(gx - x) <= tx and abs(gy - y) <= ty


@given(image_points())
@settings(max_examples=50, deadline=None)
def test_points_inside_reasoning_and_bare_tuple(data):
    W, H, pts = data
    body = format_points(pts, W, H, "normalized")
    wrapped = f"<think>[Position] [the cup]: (0.100, 0.200)</think><answer>{body}</answer>"
    assert parse_points(wrapped, W, H) == parse_points(body, W, H)  # the think block's point is not an answer
    bare = body[1:-1]  # "(x, y), ..." without the list brackets: the paper's bare form
    assert parse_points(bare, W, H) == parse_points(body, W, H)


def test_points_auto_follows_roborefer_rule_and_rejects_garbage():
    assert parse_points("[(0.5, 0.25)]", 200, 100) == [(100.0, 25.0)]
    assert parse_points("[(120, 40)]", 200, 100) == [(120.5, 40.5)]  # integers: absolute pixels
    assert parse_points('<points x1="10" y1="20" x2="50.5" y2="50" alt="a">a</points>', 200, 100) == [(20.0, 20.0), (101.0, 50.0)]
    assert parse_points('[{"bbox_2d": [10, 20, 30, 40], "label": "cup"}]', 200, 100) == [(20.5, 30.5)]
    assert parse_points("I cannot see it.", 200, 100) == []
    assert parse_points("", 200, 100) == []
    with pytest.raises(ValueError):
        parse_points("(1, 2)", 10, 10, "percent")


@settings(max_examples=200, deadline=None)
@given(st.lists(st.text(alphabet="abcdefghij ", min_size=1, max_size=12).map(str.strip).filter(bool),
                min_size=2, max_size=6, unique=True), st.data())
def test_choice_round_trip(options, data):
    k = data.draw(st.integers(0, len(options) - 1))
    letter = "ABCDEFGH"[k]
    for text in (f"({letter})", f"({letter}) {options[k]}", f"{letter}", f"{letter}.", f"Answer: {letter}",
                 f"<think>x</think><answer>({letter})</answer>"):
        assert parse_choice(text, options) == k, text


def test_choice_by_option_text_and_ambiguity():
    assert parse_choice("Yes, it is.", ["no", "yes"]) == 1
    assert parse_choice("left", ["right", "left"]) == 1
    assert parse_choice("(A) or (B)", ["no", "yes"]) is None  # two letters: no answer
    assert parse_choice("maybe", ["no", "yes"]) is None
    assert parse_choice("(C)", ["no", "yes"]) is None  # a letter past the options
    assert parse_choice("(B)", ["", "", ""]) == 1  # visual choice: options are marks, letters only


@settings(max_examples=200, deadline=None)
@given(st.floats(0.001, 50.0), st.sampled_from(["m", "cm", "mm", "ft", "in", "meters", "centimeters", "inches", "feet"]))
def test_length_round_trip(v, unit):
    got = parse_number(format_number(v, "length", unit), "length")
    assert got == pytest.approx(v, rel=1e-3)


@settings(max_examples=100, deadline=None)
@given(st.floats(0.0, math.pi), st.sampled_from(["degrees", "deg", "°", "rad"]))
def test_angle_round_trip(v, unit):
    assert parse_number(format_number(v, "angle", unit), "angle") == pytest.approx(v, rel=1e-3, abs=1e-6)


def test_number_forms():
    assert parse_number("35 centimeters", "length") == pytest.approx(0.35)
    assert parse_number("1.70 meters", "length") == pytest.approx(1.70)
    assert parse_number("1 m 20 cm", "length") == pytest.approx(1.20)
    assert parse_number("5 ft 3 in", "length") == pytest.approx(5 * 0.3048 + 3 * 0.0254)
    assert parse_number("0.4", "length") == pytest.approx(0.4)  # bare: metres
    assert parse_number("12", "angle") == pytest.approx(math.radians(12))  # bare: degrees
    assert parse_number("3 in the box", "length") == pytest.approx(3.0)  # a preposition, not inches
    assert parse_number("rotate left around 19.9 degrees", "angle", signed_by_direction=True) == pytest.approx(-math.radians(19.9))
    assert parse_number("rotate up around 5 degrees", "angle", signed_by_direction=True) == pytest.approx(math.radians(5))
    assert parse_number("about 30 degrees", "length") is None  # an angle is not a length
    assert parse_number("no idea", "length") is None
    assert set(LENGTH_UNITS) >= {"m", "cm", "mm", "ft", "in"}


def test_reasoning_structure_and_steps():
    t = "<think>[Position] [the red cup]: (0.510, 0.255)\n[Size] [the red cup]: 0.12 m\n[Orientation] [the mug]: (0.1, 0.2, 0.97)</think><answer>[(0.510, 0.255)]</answer>"
    think, ans = split_reasoning(t)
    assert ans == "[(0.510, 0.255)]" and answer_part(t) == ans
    steps, bad = parse_steps(think)
    assert bad == 0 and [s.type for s in steps] == ["Position", "Size", "Orientation"]
    assert steps[1].value == pytest.approx((0.12,))
    assert split_reasoning("<think>a</think>") is None
    assert split_reasoning("x <think>a</think><answer>b</answer>") is None  # text outside the tags
    assert split_reasoning("<think>a</think><answer>b</answer><answer>c</answer>") is None
    assert parse_steps("[Position] [cup]: nowhere\nrandom words")[1] == 2
    # Size: RoboRefer's scalar in several spellings, and the older 3-vector
    assert parse_step_value("Size", "(0.200)") == pytest.approx((0.2,))
    assert parse_step_value("Size", "20 cm") == pytest.approx((0.2,))
    assert parse_step_value("Size", "(0.125, 0.120, 0.200)") == pytest.approx((0.125, 0.12, 0.2))
    assert parse_step_value("Orientation", "(1, 0)") is None
